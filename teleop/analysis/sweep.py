"""The delay sweep: run the loop over a grid of delays, losses and controllers; classify each run.

:func:`run_delay_sweep` is independent of *how* a run is executed: it is given a
:data:`PointRunner` (a picklable top-level function ``runner(cfg, duration_s) -> RunSignals``)
that runs the full loop for one configured point.  The CLI wires in the services' lockstep
runner (in-process bus, virtual clock) or the live zenoh services.  Points run in a ``spawn``
process pool when ``workers > 1``; every point's seeds derive from the sweep seed and the
point's own indices, so results do not depend on the order or the pool size.

After the grid, the largest stable delay of every controller at zero loss is bracketed by
the grid and, when ``refine_steps > 0``, narrowed by bisection (extra runs) so it can be set
beside the linearised loop's prediction.
"""

from __future__ import annotations

import math
import multiprocessing
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np

from teleop.analysis.stability import RunMetrics, RunSignals, StabilityCriteria, classify_run
from teleop.analysis.sweep_signals import round_trip_s, settle_time_s
from teleop.config import TeleopConfig
from teleop.errors import UserInputError

__all__ = ["SweepPoint", "SweepRun", "SweepResult", "PointRunner", "ProgressFn",
           "point_config", "run_delay_sweep", "max_stable_delay", "point_duration_s",
           "run_points"]

PointRunner = Callable[[TeleopConfig, float], RunSignals]
ProgressFn = Callable[[int, int, "SweepRun"], None]


@dataclass(frozen=True, slots=True)
class SweepPoint:
    """One point of the grid: controller, one-way master<->controller delay, jitter, loss
    (both links), and optionally the operator style, the object and the jitter law."""

    controller: str
    delay_s: float
    jitter_s: float
    loss: float
    seed: int
    operator: str = ""  # master.virtual.style ("" = as configured)
    object: str = ""  # a name of teleop.analysis.sweep_objects.OBJECTS ("" = as configured)
    jitter: str = ""  # jitter law ("" = uniform when jitter_s > 0)


@dataclass(frozen=True, slots=True)
class SweepRun:
    """A point and its metrics."""

    point: SweepPoint
    metrics: RunMetrics
    wall_s: float
    refine: bool = False  # an extra run of the bisection for the largest stable delay
    signals: RunSignals | None = field(default=None, compare=False, repr=False)
    extra: tuple[tuple[str, Any], ...] = ()  # extra JSON keys (endurance)

    def row(self) -> dict[str, Any]:
        """The JSON row (DESIGN.md contract keys first, then extras)."""
        m = self.metrics
        worst = max(m.oscillations, key=lambda o: o.index, default=None)
        return {
            "controller": self.point.controller, "delay_s": self.point.delay_s,
            "jitter_s": self.point.jitter_s, "loss": self.point.loss, "stable": m.stable,
            "passive": m.passive, "energy_generated_j": m.energy_generated_j,
            "tracking_rms_rad": m.tracking_rms_rad, "force_rms_n": m.force_rms_n,
            "tracking_hold_rad": m.tracking_hold_rad,
            "tank_min_j": m.tank_min_j, "operator": self.point.operator,
            "object": self.point.object, "passive_audit": m.passive_audit,
            "audit_energy_generated_j": m.audit_energy_generated_j,
            "felt_true_force_ratio": m.felt_true_force_ratio,
            "passive_ledger": m.passive_ledger,
            "ledger_audit_gap_operator_j": m.ledger_audit_gap_operator_j,
            "ledger_audit_gap_environment_j": m.ledger_audit_gap_environment_j,
            "jitter": self.point.jitter or ("uniform" if self.point.jitter_s > 0 else "none"),
            "oscillation_amplitude": worst.amplitude if worst else 0.0,
            "oscillation_frequency_hz": worst.frequency_hz if worst else math.nan,
            "oscillation_signal": worst.name if worst else "",
            "oscillation": {o.name: o.as_dict() for o in m.oscillations},
            "limited_count": m.limited_count,
            "limited_fraction": m.limited_fraction, "dropped_messages": m.dropped_messages,
            "oscillation_index": m.oscillation_index, "growth_ratio": m.growth_ratio,
            "hf_power_fraction": m.hf_power_fraction, "reason": m.reason,
            "stability_judged": m.judged,
            "seed": self.point.seed, "refine": self.refine, "wall_s": self.wall_s,
            **dict(self.extra),
        }


@dataclass(frozen=True, slots=True)
class SweepResult:
    """All runs of a sweep, the predicted and the measured largest stable delays."""

    runs: tuple[SweepRun, ...]
    predicted_max_stable_delay_s: tuple[tuple[str, float], ...]
    measured_max_stable_delay_s: tuple[tuple[str, float], ...]
    measured_bracket_s: tuple[tuple[str, float, float], ...]
    mode: str
    seed: int
    duration_s: float
    wall_s: float
    notes: tuple[str, ...] = field(default=())
    interrupted: bool = False  # stopped by Ctrl-C: ``runs`` are the ones finished by then

    def grid_runs(self) -> tuple[SweepRun, ...]:
        """The grid runs (without the bisection runs)."""
        return tuple(r for r in self.runs if not r.refine)

    def to_json(self) -> dict[str, Any]:
        """The ``teleop sweep --json`` object (DESIGN.md contract plus extra keys)."""
        return {
            "runs": [r.row() for r in self.runs],
            "predicted_max_stable_delay_s": dict(self.predicted_max_stable_delay_s),
            "measured_max_stable_delay_s": dict(self.measured_max_stable_delay_s),
            "measured_bracket_s": {c: [lo, hi] for c, lo, hi in self.measured_bracket_s},
            "mode": self.mode, "seed": self.seed, "duration_s": self.duration_s,
            "wall_s": self.wall_s, "notes": list(self.notes),
            "interrupted": self.interrupted,
        }


def point_config(cfg: TeleopConfig, p: SweepPoint) -> TeleopConfig:
    """``cfg`` with the point's controller, delay, jitter, loss, operator, object and seeds.

    Delay and jitter act on the master<->controller link in both directions; loss on both
    links (master<->controller and controller<->hand), both directions.
    """
    from teleop.analysis.sweep_objects import OBJECTS, with_object

    link = cfg.links.master_controller
    law = p.jitter or (("uniform" if p.jitter_s > 0 else "none") if link.jitter == "none"
                       else link.jitter)
    link = replace(link, delay_s=p.delay_s, backward_delay_s=None, loss=p.loss,
                   jitter=law if p.jitter_s > 0 else "none", jitter_s=p.jitter_s, seed=p.seed)
    hand_link = replace(cfg.links.controller_hand, loss=p.loss, seed=p.seed + 1)
    links = replace(cfg.links, master_controller=link, controller_hand=hand_link)
    cfg = replace(cfg, links=links, controller=replace(cfg.controller, kind=p.controller),
                  session=replace(cfg.session, seed=p.seed))
    if p.operator:
        cfg = replace(cfg, master=replace(cfg.master, virtual=replace(cfg.master.virtual,
                                                                      style=p.operator)))
    return with_object(cfg, p.object) if p.object in OBJECTS else cfg  # else: a label


def point_duration_s(cfg: TeleopConfig, duration_s: float) -> float:
    """``duration_s``, lengthened so that three round trips and 1.5 s follow the settling.

    A long delay makes a slow loop: its oscillation can only be told from a transient after
    a few round trips.
    """
    settle = settle_time_s(cfg)
    if settle <= 0:
        return duration_s
    return max(duration_s, settle + 3.0 * round_trip_s(cfg) + 1.5)


def _point_seed(seed: int, ci: int, di: int, li: int) -> int:
    return (seed * 1_000_003 + ci * 10_007 + di * 101 + li * 7) % (2**31 - 1)


def decimate(s: RunSignals, rate_hz: float = 200.0) -> RunSignals:
    """``s`` keeping about ``rate_hz`` samples per second (for logging and plotting)."""
    if len(s.t_s) < 2:
        return s
    step = max(1, int(round(1.0 / (rate_hz * float(np.median(np.diff(s.t_s)))))))
    arrays = {f: getattr(s, f)[::step] for f in ("t_s", "setpoint_rad", "finger_rad",
                                                 "force_displayed_n", "force_measured_n",
                                                 "energy_out_j", "energy_in_j", "tank_j",
                                                 "fingers_rad", "trigger_m", "audit_margin_j")
              if getattr(s, f) is not None}
    return replace(s, **arrays)


def _run_one(runner: PointRunner, cfg: TeleopConfig, point: SweepPoint, duration_s: float,
             criteria: StabilityCriteria, refine: bool, keep: bool = False) -> SweepRun:
    t0 = time.perf_counter()
    pcfg = point_config(cfg, point)
    signals = runner(pcfg, point_duration_s(pcfg, duration_s))
    metrics = classify_run(signals, criteria)
    return SweepRun(point, metrics, time.perf_counter() - t0, refine,
                    decimate(signals) if keep else None)


def run_points(runner: PointRunner, cfg: TeleopConfig, points: Sequence[SweepPoint],
               duration_s: float, criteria: StabilityCriteria, workers: int,
               done: Callable[[SweepRun], None]) -> list[SweepRun]:
    """Run and classify ``points`` (spawn pool when ``workers > 1``), in order."""
    pool = _Pool(workers)
    try:
        return pool.map(_run_one, [(runner, cfg, p, duration_s, criteria, False)
                                   for p in points], done)
    finally:
        pool.close()


def max_stable_delay(runs: Sequence[SweepRun], controller: str,
                     loss: float = 0.0) -> tuple[float, float]:
    """(largest delay with every delay up to it stable, smallest unstable delay above it).

    Only the runs of ``controller`` at ``loss``; ``inf`` when no run is unstable.
    """
    pts = sorted((r.point.delay_s, r.metrics.stable) for r in runs
                 if r.point.controller == controller and r.point.loss == loss)
    lo, hi = math.nan, math.inf
    for d, stable in pts:
        if not stable:
            hi = d
            break
        lo = d
    return lo, hi


def _job_seconds(job: tuple[Any, ...]) -> float:
    """Simulated seconds of a ``_run_one`` job ``(runner, cfg, point, duration_s, ...)``
    (0 for anything else)."""
    if len(job) < 4 or not isinstance(job[2], SweepPoint):
        return 0.0
    return point_duration_s(point_config(job[1], job[2]), job[3])


class _Pool:
    """Serial or spawn-process execution of runs; results in the order of the jobs."""

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self._ex: ProcessPoolExecutor | None = None
        if workers > 1:
            self._ex = ProcessPoolExecutor(workers,
                                           mp_context=multiprocessing.get_context("spawn"))

    def map(self, fn: Callable[..., SweepRun], jobs: list[tuple[Any, ...]],
            done: Callable[[SweepRun], None]) -> list[SweepRun]:
        if self._ex is None:
            out = []
            for job in jobs:
                out.append(fn(*job))
                done(out[-1])
            return out
        # the longest runs first (simulated seconds), so no worker is left with a long run at
        # the end; each result still goes to its own place, the order of ``jobs``
        # (``done`` hears of each run as it finishes: waiting in job order would hold the
        # progress bar back until the first job, which may be one of the last to start)
        order = sorted(range(len(jobs)), key=lambda i: -_job_seconds(jobs[i]))
        index = {self._ex.submit(fn, *jobs[i]): i for i in order}
        results: list[SweepRun | None] = [None] * len(jobs)
        for fut in as_completed(index):
            run = fut.result()
            results[index[fut]] = run
            done(run)
        return [r for r in results if r is not None]

    def close(self) -> None:
        if self._ex is not None:  # (after Ctrl-C: the runs not yet started are dropped)
            self._ex.shutdown(cancel_futures=True)


def default_runner(mode: str) -> PointRunner:
    """The point runner of ``mode``: ``lockstep`` (services' lockstep runner) or ``live``."""
    from teleop.commands import sweep as cli_sweep  # the CLI layer wires in the services

    runners = {"lockstep": cli_sweep.lockstep_runner, "live": cli_sweep.live_runner}
    if mode not in runners:
        raise UserInputError(f"sweep mode {mode!r}: expected lockstep or live")
    return runners[mode]


def run_delay_sweep(
    cfg: TeleopConfig,
    delays_s: Sequence[float],
    losses: Sequence[float],
    controllers: Sequence[str],
    mode: str = "lockstep",
    seed: int = 0,
    duration_s: float = 6.0,
    progress: ProgressFn | None = None,
    *,
    runner: PointRunner | None = None,
    jitter_s: float = 0.0,
    workers: int = 1,
    refine_steps: int = 0,
    predicted: Sequence[tuple[str, float]] = (),
    criteria: StabilityCriteria = StabilityCriteria(),
    keep_signals: bool = False,
    refine_controllers: Sequence[str] | None = None,
) -> SweepResult:
    """Run every (controller, delay, loss) point; classify; bracket the largest stable delay."""
    if runner is None:
        runner = default_runner(mode)
    if not delays_s or not losses or not controllers:
        raise UserInputError("sweep: delays, losses and controllers must each be non-empty")
    if any(d < 0 for d in delays_s) or any(not 0 <= p <= 1 for p in losses):
        raise UserInputError("sweep: delays must be >= 0 and losses within [0, 1]")
    t0 = time.perf_counter()
    delays = sorted(set(float(d) for d in delays_s))
    from teleop.analysis.sweep_objects import object_name

    style, obj = cfg.master.virtual.style, object_name(cfg)
    points = [SweepPoint(c, d, jitter_s, float(p), _point_seed(seed, ci, di, li), style, obj)
              for ci, c in enumerate(controllers) for li, p in enumerate(losses)
              for di, d in enumerate(delays)]
    to_refine = [c for c in controllers if refine_controllers is None or c in refine_controllers]
    total = len(points) + refine_steps * (1 if 0.0 in losses else 0) * len(to_refine)
    done_runs: list[SweepRun] = []

    def done(run: SweepRun) -> None:
        done_runs.append(run)
        if progress is not None:
            progress(len(done_runs), total, run)

    runs, stop = until_interrupted(
        lambda: _schedule(workers, runner, cfg, points, controllers, to_refine, losses,
                          refine_steps, duration_s, jitter_s, seed, criteria, keep_signals,
                          done),
        done_runs, total)
    if stop is not None:
        runs = [r for r in runs if not r.refine]
    refined = [r for r in done_runs if r.refine]
    loss0 = 0.0 if 0.0 in losses else None
    brackets = [] if loss0 is None else [
        (c, *_bisect(max_stable_delay(runs, c, loss0), [r for r in refined
                                                          if r.point.controller == c]))
        for c in controllers]
    runs = runs + refined
    runs.sort(key=lambda r: (list(controllers).index(r.point.controller), r.point.loss,
                             r.point.delay_s))
    measured = tuple((c, lo) for c, lo, _ in brackets)
    return SweepResult(tuple(runs), tuple(predicted), measured, tuple(brackets), mode, seed,
                       duration_s, time.perf_counter() - t0, () if stop is None else (stop,),
                       stop is not None)


def until_interrupted(work: Callable[[], list[SweepRun]], done_runs: Sequence[SweepRun],
                      planned: int) -> tuple[list[SweepRun], str | None]:
    """``(work(), None)``; on Ctrl-C (KeyboardInterrupt) the runs finished by then
    (``done_runs``, which the work's ``done`` callback fills) and a note saying so, so a long
    sweep's finished runs are reported and written, not lost.  The runs in flight are
    dropped: each is a whole simulated run or nothing."""
    try:
        return work(), None
    except KeyboardInterrupt:
        return list(done_runs), (f"interrupted (Ctrl-C) after {len(done_runs)} of {planned} "
                                 "runs: the report and its files hold those runs only")


def _bisect(bracket: tuple[float, float], steps: Sequence[SweepRun]) -> tuple[float, float]:
    """``bracket`` narrowed by the bisection runs ``steps`` (in step order)."""
    lo, hi = bracket
    for run in steps:
        lo, hi = (run.point.delay_s, hi) if run.metrics.stable else (lo, run.point.delay_s)
    return lo, hi


def _refinable(bracket: tuple[float, float]) -> bool:
    lo, hi = bracket
    return math.isfinite(hi) and not math.isnan(lo)


def _schedule(workers: int, runner: PointRunner, cfg: TeleopConfig,
              points: Sequence[SweepPoint], controllers: Sequence[str],
              to_refine: Sequence[str], losses: Sequence[float], steps: int,
              duration_s: float, jitter_s: float, seed: int, criteria: StabilityCriteria,
              keep: bool, done: Callable[[SweepRun], None]) -> list[SweepRun]:
    """Run the grid ``points`` (results in their order) and bisect each controller of
    ``to_refine`` at zero loss for ``steps`` steps (results only through ``done``).

    A controller's bisection starts as soon as its zero-loss grid runs are in (those run
    first) and each step as soon as the one before it is, ahead of the rest of the grid
    (:class:`~teleop.analysis.sweep_schedule.JobQueue`): the same runs as bisecting after
    the whole grid, without the workers idling through the bisection."""
    from teleop.analysis.sweep_schedule import JobQueue

    loss0 = 0.0 if 0.0 in losses and steps > 0 else None
    refine = [c for c in to_refine if loss0 is not None]
    grid: list[SweepRun | None] = [None] * len(points)
    waiting = {c: sum(1 for p in points if p.controller == c and p.loss == loss0)
               for c in refine}
    queue = JobQueue(workers)

    def bisect_step(c: str, step: int, bracket: tuple[float, float]) -> None:
        if step >= steps or not _refinable(bracket):
            return
        lo, hi = bracket
        p = SweepPoint(c, 0.5 * (lo + hi), jitter_s, 0.0,
                       _point_seed(seed, list(controllers).index(c), 1000 + step, 0),
                       cfg.master.virtual.style, points[0].object)

        def then(run: SweepRun) -> None:
            done(run)
            bisect_step(c, step + 1, _bisect(bracket, [run]))

        queue.add((0.0,), _run_one, (runner, cfg, p, duration_s, criteria, True), then)

    def grid_done(i: int) -> Callable[[SweepRun], None]:
        def then(run: SweepRun) -> None:
            grid[i] = run
            done(run)
            c = run.point.controller
            if c in waiting and run.point.loss == loss0:
                waiting[c] -= 1
                if waiting[c] == 0:
                    bisect_step(c, 0, max_stable_delay([r for r in grid if r is not None],
                                                       c, 0.0))
        return then

    try:
        for i, p in enumerate(points):
            job = (runner, cfg, p, duration_s, criteria, False, keep)
            first = p.controller in waiting and p.loss == loss0
            queue.add((1.0 if first else 2.0, -_job_seconds(job)), _run_one, job,
                      grid_done(i))
        queue.run()
    finally:
        queue.close()
    return [r for r in grid if r is not None]


def as_dict(run: SweepRun) -> dict[str, Any]:
    """A plain dict of a run (for logging)."""
    return {"point": asdict(run.point), "metrics": asdict(run.metrics), "wall_s": run.wall_s}
