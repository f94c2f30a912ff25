"""Endurance (``teleop sweep --endurance``): long lockstep runs of the operator's repeated
grasps, every grasp judged against the first (:mod:`teleop.analysis.grasps`).

The scenario is the configuration's own operator - by default the relaxed operator's
repeating script (wait 0.5 s, close the trigger fully over 1 s, hold 2 s, open over 1 s: a
grasp every 4.5 s) on the stiff cylinder, exactly what ``teleop up`` runs - not the sweep's
single-grasp scenario.  Each controller runs at 0, 0.2 and 1 s one-way master<->controller
delay with 20 % loss on both links.  The run is also classified like a sweep point
(stability in every hold, passivity by the physical audit).

The library does not import ``services``: the CLI hands in an :data:`EnduranceRunner`
(``runner(cfg, duration_s) -> (RunSignals, GraspSeries)``, picklable, top level).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from teleop.analysis.grasps import (
    GraspSeries,
    curl_grasps,
    format_grasps,
    grasp_threshold_m,
)
from teleop.analysis.stability import RunSignals, StabilityCriteria, classify_run
from teleop.analysis.sweep import (
    ProgressFn,
    SweepPoint,
    SweepResult,
    SweepRun,
    _Pool,
    point_config,
    until_interrupted,
)
from teleop.analysis.sweep_objects import object_name
from teleop.config import TeleopConfig

Array = NDArray[np.float64]
EnduranceRunner = Callable[[TeleopConfig, float], tuple[RunSignals, GraspSeries]]

__all__ = ["ENDURANCE_DELAYS_S", "ENDURANCE_LOSS", "EnduranceRunner", "grasp_threshold_m",
           "grasps_from_columns", "run_endurance", "format_endurance"]

ENDURANCE_DELAYS_S: tuple[float, ...] = (0.0, 0.2, 1.0)
ENDURANCE_LOSS = 0.2


def grasps_from_columns(t_s: Array, trigger_m: Array, pressure: Array, proximal_rad: Array,
                        distal_rad: Array, displayed_force_n: Array,
                        cfg: TeleopConfig) -> GraspSeries:
    """:func:`curl_grasps` with the configuration's grasp threshold."""
    return curl_grasps(t_s, trigger_m, pressure, proximal_rad, distal_rad, displayed_force_n,
                       grasp_threshold_m(cfg))


def _endurance_one(runner: EnduranceRunner, cfg: TeleopConfig, point: SweepPoint,
                   duration_s: float, criteria: StabilityCriteria) -> SweepRun:
    t0 = time.perf_counter()
    signals, grasps = runner(point_config(cfg, point), duration_s)
    m = classify_run(signals, criteria)
    extra: tuple[tuple[str, Any], ...] = (
        ("endurance_min_grasp_ratio", grasps.min_pressure_ratio),
        ("endurance_min_felt_ratio", grasps.min_felt_ratio),
        ("endurance_min_closure_ratio", grasps.min_closure_ratio),
        ("grasp_count", len(grasps.grasps)),
        ("grasps", grasps.rows()),
    )
    return SweepRun(point, m, time.perf_counter() - t0, extra=extra)


def run_endurance(cfg: TeleopConfig, controllers: Sequence[str], runner: EnduranceRunner,
                  *, minutes: float = 10.0, delays_s: Sequence[float] = ENDURANCE_DELAYS_S,
                  loss: float = ENDURANCE_LOSS, seed: int = 0, workers: int = 1,
                  progress: ProgressFn | None = None,
                  criteria: StabilityCriteria = StabilityCriteria()) -> SweepResult:
    """One long run per controller and delay; per-grasp statistics in each row's extras."""
    t0 = time.perf_counter()
    style, obj = cfg.master.virtual.style, object_name(cfg)
    points = [SweepPoint(c, float(d), 0.0, loss,
                         (seed * 1_000_003 + ci * 10_007 + di * 101 + 50_000) % (2**31 - 1),
                         style, obj)
              for ci, c in enumerate(controllers) for di, d in enumerate(delays_s)]
    done_runs: list[SweepRun] = []

    def done(run: SweepRun) -> None:
        done_runs.append(run)
        if progress is not None:
            progress(len(done_runs), len(points), run)

    pool = _Pool(workers)
    try:
        runs, stop = until_interrupted(
            lambda: pool.map(_endurance_one, [(runner, cfg, p, 60.0 * minutes, criteria)
                                              for p in points], done),
            done_runs, len(points))
    finally:
        pool.close()
    order = {p: i for i, p in enumerate(points)}
    runs.sort(key=lambda r: order[r.point])
    note = (f"endurance: {minutes:g} simulated minutes of repeated grasps per run "
            f"({style} operator, {obj}), loss {loss:.0%} on both links")
    return SweepResult(tuple(runs), (), (), (), "lockstep", seed, 60.0 * minutes,
                       time.perf_counter() - t0, (note,) if stop is None else (note, stop),
                       stop is not None)


_GROWTH_ONLY = " (growth only: every hold shorter than the round trip)"


def format_endurance(result: SweepResult, every: int = 20) -> str:
    """Per run: the summary line and a per-grasp table (every ``every``-th grasp)."""
    from teleop.analysis.grasps import GraspStats

    lines = []
    for r in result.runs:
        ex = dict(r.extra)
        gs = GraspSeries(tuple(GraspStats(g["grasp"], g["t_start_s"], g["t_end_s"],
                                          g["peak_pressure"], g["closure_rad"],
                                          g["felt_force_n"], g["pressure_ratio"],
                                          g["closure_ratio"], g["felt_ratio"],
                                          g.get("peak_closure_rad", float("nan")))
                               for g in ex.get("grasps", [])))
        m = r.metrics
        lines.append(
            f"{r.point.controller} {r.point.delay_s * 1000:.0f} ms loss {r.point.loss:.0%}: "
            f"{ex.get('grasp_count', 0)} grasps, weakest/first peak pressure "
            f"{ex.get('endurance_min_grasp_ratio', float('nan')):.2f}, felt "
            f"{ex.get('endurance_min_felt_ratio', float('nan')):.2f}, closure "
            f"{ex.get('endurance_min_closure_ratio', float('nan')):.2f}; "
            f"{'stable' if m.stable else 'UNSTABLE'}"
            f"{_GROWTH_ONLY if m.judged == 'growth only' else ''}, "
            f"{'passive' if m.passive else 'NOT passive'} (audit), "
            f"tank min {m.tank_min_j:.3g} J")
        lines.append(format_grasps(gs, every))
        lines.append("")
    lines.extend(f"note: {n}" for n in result.notes)
    return "\n".join(lines)
