"""Generated proof batch for ``teleop diagnose --model finger`` on dynamic finger recordings.

Each case is a 3 s ``force-step`` recording (:mod:`sim.experiments`) with one concealed effect of
random magnitude, or none, diagnosed by :func:`sim.finger_dynamic.diagnose_dynamic`.

    python -m sim.finger_diagnose_batch [PER_CLASS] [SEED] [--all]

``--all`` adds dead_time and actuator_saturation, which one force step cannot identify.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass

import numpy as np

from sim.experiments import ExperimentSpec, run_experiment
from sim.finger import ContactObject
from sim.finger_dynamic import FingerDynamicModel, dynamic_data
from sim.params import default_finger_params
from teleop.diagnose.select_sim import diagnose_dynamic
from teleop.effects import EffectSet

RANGES: dict[str, tuple[float, float]] = {
    "coulomb_friction": (0.8, 2.0),      # N of tendon force (the motor's own is 1 N)
    "actuator_lag": (0.03, 0.08),        # s
    "sensor_offset": (0.03, 0.08),       # rad, random sign
    "backlash": (0.02, 0.06),            # rad of motor shaft
    "actuator_gain": (0.6, 0.85),        # or its inverse (random)
}
NOT_FROM_ONE_STEP: dict[str, tuple[float, float]] = {
    "dead_time": (0.03, 0.08),           # s (read as actuator_lag)
    "actuator_saturation": (4.0, 10.0),  # N (one force level: read as a gain)
}
TOLERANCE = 0.05
DURATION_S = 3.0


@dataclass(frozen=True, slots=True)
class CaseResult:
    """One case: what was concealed, what was found first (None: nothing)."""

    concealed: str | None
    value: float
    found: str | None
    found_value: float


def cases(seed: int, per_class: int, ranges: dict[str, tuple[float, float]] = RANGES
          ) -> list[tuple[str | None, float]]:
    """``per_class`` clean cases, then ``per_class`` random magnitudes of every effect."""
    rng = np.random.default_rng(seed)
    out: list[tuple[str | None, float]] = [(None, 0.0)] * per_class
    for name, (lo, hi) in ranges.items():
        for _ in range(per_class):
            v = float(rng.uniform(lo, hi))
            if name == "sensor_offset" and rng.random() < 0.5:
                v = -v
            if name == "actuator_gain" and rng.random() < 0.5:
                v = 1.0 / v
            out.append((name, v))
    return out


def run_case(name: str | None, value: float) -> CaseResult:
    """Generate one recording and diagnose it."""
    p = default_finger_params()
    eff = EffectSet() if name is None else EffectSet().with_effect(name, value)
    rec = run_experiment(ExperimentSpec("force-step", duration_s=DURATION_S), p,
                         ContactObject(kind="none"), eff).recording
    d = diagnose_dynamic(FingerDynamicModel(p, dynamic_data(rec, "motor_angle_rad"), TOLERANCE))
    if d.chosen:
        return CaseResult(name, value, d.chosen[0][0], d.chosen[0][1])
    return CaseResult(name, value, None, 0.0)


def main(argv: list[str]) -> int:
    """Print hits per class."""
    pos = [a for a in argv if not a.startswith("--")]
    per_class = int(pos[0]) if pos else 6
    seed = int(pos[1]) if len(pos) > 1 else 777
    ranges = {**RANGES, **NOT_FROM_ONE_STEP} if "--all" in argv else RANGES
    t0 = time.perf_counter()
    stats: dict[str, list[CaseResult]] = {}
    for name, value in cases(seed, per_class, ranges):
        stats.setdefault(name or "clean", []).append(run_case(name, value))
    for k, rs in stats.items():
        hits = sum(r.found == r.concealed for r in rs)
        misses = [(round(r.value, 4), r.found) for r in rs if r.found != r.concealed]
        print(f"{k}: {hits}/{len(rs)} {misses if misses else ''}")
    print(f"time {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
