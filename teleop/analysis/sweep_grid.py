"""The robustness grid (``teleop sweep --grid full``): operator x object x delay x loss x jitter
x controller, every point classified like the delay sweep.

Every point runs the sweep's scenario (``sweep.scenario``: one close to 60 % of the trigger's
travel, then a hold) with the point's operator style and object (presets in
:mod:`teleop.analysis.sweep_objects`); stability is judged in the hold, where the grasp is in
contact with every object but free air.  Loss (Bernoulli) acts on both links, both directions;
jitter (Pareto/Lomax, shape 2.5) on the master<->controller link, both directions.

:data:`FULL` is the grid of the issue; :data:`REDUCED` the small one CI runs.
"""

from __future__ import annotations

import itertools
import math
import statistics
import time
from collections.abc import Sequence
from dataclasses import dataclass

from teleop.analysis.stability import StabilityCriteria
from teleop.analysis.sweep import (
    PointRunner,
    ProgressFn,
    SweepPoint,
    SweepResult,
    SweepRun,
    run_points,
    until_interrupted,
)
from teleop.analysis.sweep_objects import OBJECTS, OPERATORS
from teleop.config import TeleopConfig
from teleop.errors import UserInputError

__all__ = ["GridSpec", "FULL", "REDUCED", "GRIDS", "grid_points", "run_grid", "format_grid"]


@dataclass(frozen=True, slots=True)
class GridSpec:
    """The axes of a robustness grid."""

    operators: tuple[str, ...]
    objects: tuple[str, ...]
    delays_s: tuple[float, ...]
    losses: tuple[float, ...]
    jitters: tuple[tuple[str, float], ...]  # (law, scale s); ("none", 0) for no jitter
    duration_s: float  # per run, lengthened for long delays (point_duration_s)

    @property
    def size_per_controller(self) -> int:
        return (len(self.operators) * len(self.objects) * len(self.delays_s)
                * len(self.losses) * len(self.jitters))


#: the issue's grid: 3 x 5 x 4 x 2 x 2 = 240 runs per controller (192 before the crushable
#: cylinder), 5 s each (1 s delay: 11 s)
FULL = GridSpec(OPERATORS, tuple(OBJECTS), (0.0, 0.05, 0.2, 1.0), (0.0, 0.2),
                (("none", 0.0), ("pareto", 0.01)), 5.0)
#: CI's grid: the corners (8 runs per controller)
REDUCED = GridSpec(("soft", "hard"), ("free-air", "stiff-cylinder"), (0.0, 1.0), (0.2,),
                   (("pareto", 0.01),), 4.0)
GRIDS = {"full": FULL, "reduced": REDUCED}


def grid_points(spec: GridSpec, controllers: Sequence[str], seed: int) -> list[SweepPoint]:
    """Every point of ``spec`` for ``controllers``, seeded from ``seed`` and its indices."""
    bad = [o for o in spec.objects if o not in OBJECTS]
    if bad:
        raise UserInputError(f"grid object {bad[0]!r}: expected one of {', '.join(OBJECTS)}")
    pts = []
    axes = (enumerate(controllers), enumerate(spec.operators), enumerate(spec.objects),
            enumerate(spec.losses), enumerate(spec.jitters), enumerate(spec.delays_s))
    for idx in itertools.product(*axes):
        (ci, c), (oi, op), (bi, ob), (li, loss), (ji, (law, scale)), (di, d) = idx
        flat = ((((ci * 8 + oi) * 8 + bi) * 8 + li) * 8 + ji) * 64 + di
        pts.append(SweepPoint(c, float(d), scale, float(loss),
                              (seed * 1_000_003 + flat * 7_919) % (2**31 - 1), op, ob,
                              law if scale > 0 else "none"))
    return pts


def run_grid(cfg: TeleopConfig, spec: GridSpec, controllers: Sequence[str], runner: PointRunner,
             *, seed: int = 0, workers: int = 1, progress: ProgressFn | None = None,
             criteria: StabilityCriteria = StabilityCriteria()) -> SweepResult:
    """Run the grid (spawn pool when ``workers > 1``) and classify every point."""
    t0 = time.perf_counter()
    points = grid_points(spec, controllers, seed)
    done_runs: list[SweepRun] = []

    def done(run: SweepRun) -> None:
        done_runs.append(run)
        if progress is not None:
            progress(len(done_runs), len(points), run)

    runs, stop = until_interrupted(
        lambda: run_points(runner, cfg, points, spec.duration_s, criteria, workers, done),
        done_runs, len(points))
    order = {p: i for i, p in enumerate(points)}
    runs.sort(key=lambda r: order[r.point])
    note = (f"grid: {len(spec.operators)} operators x {len(spec.objects)} objects x "
            f"{len(spec.delays_s)} delays x {len(spec.losses)} losses x {len(spec.jitters)} "
            f"jitters x {len(controllers)} controllers = {len(points)} runs, "
            f"{spec.duration_s:g} s each (lengthened for long delays)")
    return SweepResult(tuple(runs), (), (), (), "lockstep", seed, spec.duration_s,
                       time.perf_counter() - t0, (note,) if stop is None else (note, stop),
                       stop is not None)


def _share(runs: Sequence[SweepRun], key: str) -> str:
    n = sum(bool(getattr(r.metrics, key)) for r in runs)
    return f"{n}/{len(runs)}"


def _median(values: Sequence[float]) -> float:
    vals = [v for v in values if math.isfinite(v)]
    return statistics.median(vals) if vals else math.nan


def _worst_unstable_index(run: SweepRun) -> float:
    """The largest amplitude-over-threshold among the run's *unstable* oscillations (-1: none;
    a slow drift can have a larger index and still not be an oscillation)."""
    return max((o.index for o in run.metrics.oscillations if o.unstable), default=-1.0)


def format_grid(result: SweepResult) -> str:
    """One line per controller x operator x object: stable/passive shares, felt force ratio,
    force and tracking errors, the worst oscillation."""
    head = (f"{'controller':<10} {'operator':<8} {'object':<18} {'stable':>7} {'passive':>7} "
            f"{'ledger':>7} {'felt/true':>9} {'force_N':>8} {'track_rad':>9}  worst oscillation")
    lines = [head, "-" * (len(head) + 12)]
    groups: dict[tuple[str, str, str], list[SweepRun]] = {}
    for r in result.runs:
        groups.setdefault((r.point.controller, r.point.operator, r.point.object), []).append(r)
    for (c, op, ob), runs in groups.items():
        worst = max(runs, key=_worst_unstable_index)
        w = max((o for o in worst.metrics.oscillations if o.unstable), key=lambda o: o.index,
                default=None)
        osc = (f"{w.name} {w.amplitude:.3g} @ {w.frequency_hz:.2f} Hz "
               f"({worst.point.delay_s * 1000:.0f} ms)" if w else "-")
        lines.append(
            f"{c:<10} {op:<8} {ob:<18} {_share(runs, 'stable'):>7} "
            f"{_share(runs, 'passive'):>7} {_share(runs, 'passive_ledger'):>7} "
            f"{_median([r.metrics.felt_true_force_ratio for r in runs]):9.2f} "
            f"{_median([r.metrics.force_rms_n for r in runs]):8.3f} "
            f"{_median([r.metrics.tracking_rms_rad for r in runs]):9.3f}  {osc}")
    lines.extend(f"note: {n}" for n in result.notes)
    return "\n".join(lines)
