"""How far each contact's last sample stands from its loading path: the set check's margins.

    python tests/teleop/control/set_check_margins.py lockstep   # elastic objects, no set
    python tests/teleop/control/set_check_margins.py harness    # the harness's quick crushes

For every contact that ends unflagged, the yield guard's set at its last sample
(:func:`teleop.control.yield_guard.set_beyond_m`) with damper allowances of 0, a half (the
guard's) and a whole sample's motion; the set check flags above one window (1 mm).
``lockstep``: 20 s of each operator x soft cylinder / stiff cylinder / block x one-way delay
0 / 0.2 / 1 s on the simulated hand (true cells), the largest per run (must stay under the
window).  ``harness``: 81 runs of the one-link harness's yielding push (operators 500 /
2,000 / 12,000 N/m x grasps of 2 / 3 / 4 s x cells reading 0.2 / 1/3 / 0.5), the smallest
and the tenth percentile (should be over it).  docs/controllers.md quotes the figures.
"""

from __future__ import annotations

import itertools
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[3]))

from teleop.control import two_layer_hand, yield_guard  # noqa: E402

ALLOWANCES = (0.0, 0.5, 1.0)
ENDS: list[tuple[float, float]] = []  # (set with no allowance, |last step|) in metres
_step = yield_guard.step_yield


def _spy(prev: yield_guard.YieldTrack, force_n: float, *a: Any, **k: Any
         ) -> yield_guard.YieldTrack:
    if force_n <= 0.0 and prev.in_contact and prev.loading and not prev.yielding:
        ENDS.append((yield_guard.set_beyond_m(prev.loading, prev.force_n, prev.advance_m, 0.0),
                     abs(prev.step_m)))
    return _step(prev, force_n, *a, **k)


def _sets_mm() -> np.ndarray:
    """Rows of the contacts ended so far, a column per allowance, in mm (and clear)."""
    e = np.array(ENDS).reshape(-1, 2) * 1e3
    ENDS.clear()
    return np.stack([e[:, 0] - a * e[:, 1] for a in ALLOWANCES], axis=1)


def lockstep() -> None:
    from services.lockstep import run_lockstep
    from teleop.analysis.sweep_objects import with_object
    from teleop.config import load_config

    for op, obj, d in itertools.product(("soft", "relaxed", "hard"),
                                        ("soft-cylinder", "stiff-cylinder", "block"),
                                        (0.0, 0.2, 1.0)):
        cfg = load_config(None, [f"master.virtual.style={op}",
                                 f"links.master_controller.delay_s={d}",
                                 f"links.controller_hand.delay_s={d}"])
        run_lockstep(with_object(cfg, obj), 20.0, seed=1)
        s = _sets_mm()
        most = "  ".join(f"{a:.1f}: {v:5.2f}" for a, v in zip(ALLOWANCES, s.max(axis=0),
                                                                strict=True)) if len(s) else "-"
        print(f"{op:8} {obj:15} {d * 1000:5.0f} ms  {len(s):3d} contacts  largest set [mm] "
              f"by allowance {most}", flush=True)


def harness() -> None:
    from dataclasses import replace

    from _ctl_harness import run_loop
    from test_assumptions import P_SET, PUSH, SUITE

    for k_op, period, gain in itertools.product((500.0, 2000.0, 12000.0), (2.0, 3.0, 4.0),
                                                (0.2, 1.0 / 3.0, 0.5)):
        run_loop(SUITE, P_SET, replace(PUSH, op_stiffness=k_op, ref_period_s=period,
                                   sensor_gain_factor=gain))
    s = _sets_mm()
    for i, a in enumerate(ALLOWANCES):
        lo, p10 = np.percentile(s[:, i], [0, 10])
        print(f"allowance {a:.1f}: {len(s)} contacts, set [mm] smallest {lo:.2f}, "
              f"tenth percentile {p10:.2f}")


if __name__ == "__main__":
    two_layer_hand.step_yield = _spy  # type: ignore[assignment]
    {"lockstep": lockstep, "harness": harness}[sys.argv[1] if len(sys.argv) > 1 else
                                               "lockstep"]()
