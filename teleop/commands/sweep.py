"""``teleop sweep``: the delay-sweep stability test (table, plot, JSON, optional rerun log).

Examples::

    teleop sweep                                   # the default lockstep sweep (config [sweep])
    teleop sweep --json sweep.json --plot docs/sweep.png
    teleop sweep --mode live --delays 0,0.05,0.2 --losses 0 --controllers two-layer --duration 5
    teleop sweep --grid full --json grid.json --plot grid.png    # heat maps grid-<ctrl>.png
    teleop sweep --endurance --endurance-minutes 1 --json endurance.json
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from concurrent.futures import ThreadPoolExecutor
from typing import TYPE_CHECKING

from teleop.commands.common import (
    FractionProgress,
    add_config_options,
    add_json_option,
    add_output_option,
    config_from_args,
    nonneg_float,
    positive_float,
    write_json,
)
from teleop.errors import UserInputError

if TYPE_CHECKING:
    from teleop.analysis.direct_limit import DirectPrediction
    from teleop.analysis.grasps import GraspSeries
    from teleop.analysis.stability import RunSignals
    from teleop.analysis.sweep import SweepResult, SweepRun
    from teleop.config import TeleopConfig


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``sweep`` subcommand."""
    p = sub.add_parser("sweep", help="delay-sweep stability test: table, plot, JSON",
                       description="Run the full loop (virtual operator, controller, simulated "
                       "hand grasping an object) over a grid of one-way delays, losses and "
                       "controllers; classify every run as stable/passive; compare the largest "
                       "stable delay of direct control with the linearised loop's prediction. "
                       "Defaults come from the [sweep] config section.")
    add_config_options(p)
    add_json_option(p)
    p.add_argument("--mode", choices=("lockstep", "live"), default="lockstep",
                   help="lockstep: in-process bus, virtual clock, deterministic (default); "
                   "live: the real services over zenoh in real time")
    p.add_argument("--seed", type=int, default=None, help="sweep seed (default: session.seed)")
    p.add_argument("--duration", type=positive_float, default=None, metavar="S",
                   help="seconds of (simulated) time per run, lengthened for long delays to "
                   "settling + 3 round trips + 1.5 s (default: sweep.duration_s)")
    p.add_argument("--delays", default=None, metavar="LIST",
                   help="comma list of one-way master<->controller delays in s")
    p.add_argument("--losses", default=None, metavar="LIST",
                   help="comma list of loss probabilities (0-1)")
    p.add_argument("--jitter", type=nonneg_float, default=None, metavar="S",
                   help="jitter scale at every point (default: sweep.jitter_s)")
    p.add_argument("--controllers", default=None, metavar="LIST",
                   help="comma list of controllers (default: sweep.controllers)")
    p.add_argument("--jobs", "--workers", dest="workers", type=int, default=None, metavar="N",
                   help="parallel runs (spawned processes; default: sweep.workers, whose "
                   "default 0 means one per core); the results do not depend on N")
    p.add_argument("--refine", type=int, default=None, metavar="N",
                   help="bisection runs that narrow each controller's largest stable delay "
                   "(default: sweep.refine_steps)")
    add_output_option(p, "--plot", what="plot", default=None, metavar="PNG",
                      help="write the sweep plot here")
    add_output_option(p, "--rerun", what="rerun log", default=None, metavar="PATH",
                      help="log every run's signals to this .rrd file")
    p.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    p.add_argument("--grid", choices=("full", "reduced"), default=None,
                   help="robustness grid instead of the delay sweep: operator style x object x "
                   "delay x loss (both links) x jitter x controller (docs/sweep.md); --plot "
                   "writes one heat map per controller (<stem>-<controller>.png)")
    p.add_argument("--endurance", action="store_true",
                   help="endurance instead of the delay sweep: long runs of repeated grasps "
                   "per controller at 0, 0.2 and 1 s delay, 20 %% loss on both links; every "
                   "grasp against the first")
    p.add_argument("--endurance-minutes", type=positive_float, default=10.0, metavar="MIN",
                   help="simulated minutes per endurance run (default 10)")
    p.set_defaults(run=run)


def _floats(text: str | None, default: tuple[float, ...], what: str) -> tuple[float, ...]:
    if text is None:
        return default
    out = []
    for item in text.split(","):
        try:
            v = float(item)
        except ValueError:
            raise UserInputError(f"--{what}: {item.strip()!r} is not a number") from None
        if not math.isfinite(v) or v < 0:
            raise UserInputError(f"--{what}: {item.strip()!r} must be a finite number >= 0")
        out.append(v)
    if not out:
        raise UserInputError(f"--{what}: empty list")
    return tuple(out)


def _names(text: str | None, default: tuple[str, ...], known: tuple[str, ...]) -> tuple[str, ...]:
    if text is None:
        return default
    names = tuple(n.strip() for n in text.split(",") if n.strip())
    if not names:
        raise UserInputError("--controllers: empty list")
    for n in names:
        if n not in known:
            raise UserInputError(f"--controllers: unknown controller {n!r} "
                                 f"(known: {', '.join(known)})")
    return names


class _Progress:
    """The shared progress bar (:class:`~teleop.commands.common.FractionProgress`) counting
    runs and saying how the last one finished."""

    def __init__(self, enabled: bool) -> None:
        self.bar = FractionProgress("", enabled)

    def __call__(self, done: int, total: int, run: SweepRun) -> None:
        total = max(total, done)
        p = run.point
        state = "stable" if run.metrics.stable else "UNSTABLE"
        state += "" if run.metrics.passive else " NOT passive"
        self.bar.draw(done / total, f"{done}/{total}",
                      f"{p.controller} {p.operator} {p.object} {p.delay_s * 1000:.0f} ms "
                      f"loss {p.loss:.0%}: {state}      ")

    def finish(self) -> None:
        self.bar.finish()


def _quiet_transport() -> None:
    """Rejected-message warnings off: a sweep counts them (``dropped_messages``), and
    hundreds of runs with jitter and loss would bury the progress bar."""
    import logging

    logging.getLogger("teleop.transport").setLevel(logging.ERROR)


def lockstep_runner(cfg: TeleopConfig, duration_s: float) -> RunSignals:
    """One point through the services' lockstep runner (a picklable top-level function)."""
    from services.lockstep import run_lockstep
    from teleop.analysis.sweep_signals import signals_from_lockstep

    _quiet_transport()
    return signals_from_lockstep(run_lockstep(cfg, duration_s), cfg)


def lockstep_endurance_runner(cfg: TeleopConfig, duration_s: float
                              ) -> tuple[RunSignals, GraspSeries]:
    """One endurance run in lockstep: its signals and every grasp (picklable, top level)."""
    from services.lockstep import run_lockstep
    from teleop.analysis.sweep_endurance import grasps_from_columns
    from teleop.analysis.sweep_signals import signals_from_lockstep

    _quiet_transport()
    res = run_lockstep(cfg, duration_s)
    grasps = grasps_from_columns(res.t_s, res.trigger_position_m, res.pressure,
                                 res.proximal_rad, res.distal_rad,
                                 res.displayed_force_n, cfg)
    return signals_from_lockstep(res, cfg), grasps


def live_runner(cfg: TeleopConfig, duration_s: float) -> RunSignals:
    """One point through the live services over zenoh (``teleop up`` in a subprocess)."""
    from teleop.analysis.sweep_live import run_live_point

    return run_live_point(cfg, duration_s)


def predict_direct(cfg: TeleopConfig) -> DirectPrediction:
    """The linearised direct loop's limit, with the hand linearised on the simulated hand."""
    from dataclasses import replace

    from sim.operator import STYLES
    from sim.params import JOINT_RATIO, default_finger_params, motor_damping_units
    from sim.sim_hand import SimHand
    from teleop.analysis.direct_limit import identify_hand, predict_direct_limit

    fp = default_finger_params()
    k_h, b_h = STYLES[cfg.master.virtual.style]
    hand = SimHand(replace(cfg.hand, sim=replace(cfg.hand.sim, noise=False)), seed=0)
    lin = identify_hand(cfg, hand, damping_units=motor_damping_units(fp, fp.max_effort_units),
                        kp_units_per_rad=fp.kp_units_per_rad, operator_stiffness_n_per_m=k_h)
    servo_k = fp.kp_units_per_rad / fp.units_per_n * fp.r_motor_m * JOINT_RATIO**2
    return predict_direct_limit(cfg, lin, operator_stiffness_n_per_m=k_h,
                                operator_damping_n_s_per_m=b_h, servo_stiffness_nm_per_rad=servo_k)


def predicted_controllers(cfg: TeleopConfig) -> tuple[str, ...]:
    """The controllers :func:`predicted_limits` predicts (and the sweep bisects)."""
    return ("direct",) if cfg.hand.backend == "sim" else ()


def predicted_limits(cfg: TeleopConfig) -> tuple[tuple[tuple[str, float], ...], tuple[str, ...]]:
    """The predicted largest stable one-way delay of direct control, and notes on it."""
    if "direct" not in predicted_controllers(cfg):
        return (), ("no prediction: the hand is linearised on the simulated hand only",)
    from teleop.control.stability_limit import loop_gain

    pred = predict_direct(cfg)
    h, lp = pred.hand, pred.loop
    note = (f"direct prediction: hand linearised at set-point {h.setpoint_rad:.3f} rad "
            f"(pressure {h.pressure:.0f}): K0 {h.gain_pressure_per_rad:.0f} /rad, motor ratio "
            f"{h.motor_ratio:.3f}, tau {h.tau_s:.3f} s (servo damping at full effort); "
            f"loop DC gain {abs(loop_gain(lp, 1e-6)):.2f}; "
            f"T_max {pred.round_trip_s * 1000:.1f} ms round trip minus "
            f"{pred.intrinsic_s * 1000:.1f} ms intrinsic latency, halved")
    return (("direct", pred.one_way_s),), (note,)


def _run_special(args: argparse.Namespace, cfg: TeleopConfig, controllers: tuple[str, ...],
                 seed: int, workers: int | None) -> int:
    """``--grid`` or ``--endurance``: lockstep only, all cores unless ``--jobs``."""
    if args.mode != "lockstep":
        raise UserInputError("--grid/--endurance: lockstep mode only (--mode live given)")
    workers = workers or os.cpu_count() or 1
    progress = _Progress(not args.no_progress)
    out = sys.stderr if args.json_path == "-" else sys.stdout
    if args.grid:
        from teleop.analysis.sweep_grid import GRIDS, format_grid, run_grid

        spec = GRIDS[args.grid]
        if args.duration is not None:
            from dataclasses import replace

            spec = replace(spec, duration_s=args.duration)
        result = run_grid(cfg, spec, controllers, lockstep_runner, seed=seed,
                          workers=workers, progress=progress)
        progress.finish()
        print(format_grid(result), file=out)
    else:
        from teleop.analysis.sweep_endurance import format_endurance, run_endurance

        result = run_endurance(cfg, controllers, lockstep_endurance_runner,
                               minutes=args.endurance_minutes, seed=seed, workers=workers,
                               progress=progress)
        progress.finish()
        print(format_endurance(result), file=out)
    print(f"{len(result.runs)} runs in {result.wall_s:.1f} s ({workers} workers)", file=out)
    write_json(args.json_path, result.to_json())
    if args.plot and args.grid and result.runs:
        from teleop.analysis.sweep_heatmap import plot_heatmaps

        for path in plot_heatmaps(result, args.plot):
            print(f"heat map: {path}", file=out)
    return _status(result, args)


def _status(result: SweepResult, args: argparse.Namespace) -> int:
    """0, or 130 (as for Ctrl-C) after an interrupted sweep wrote what it had."""
    if not result.interrupted:
        return 0
    print(f"teleop sweep: interrupted; the {len(result.runs)} finished runs are reported"
          + (f" and in {args.json_path}" if args.json_path not in (None, "-") else ""),
          file=sys.stderr)
    return 130


def run(args: argparse.Namespace) -> int:
    """Run the sweep and report."""
    from teleop.analysis.sweep import run_delay_sweep
    from teleop.analysis.sweep_report import format_table
    from teleop.config import apply_overrides
    from teleop.config.control import ControllerConfig

    cfg = config_from_args(args)
    sc = cfg.sweep
    if args.grid and args.endurance:
        raise UserInputError("--grid and --endurance: choose one")
    if args.plot and args.endurance:
        raise UserInputError("--plot: not available with --endurance (the per-grasp table "
                             "is printed and in the JSON)")
    if not args.endurance:  # endurance runs the configured operator's repeated grasps
        cfg = apply_overrides(cfg, sc.scenario)
    cfg = apply_overrides(cfg, args.overrides)  # --set wins
    known = ControllerConfig.__dataclass_fields__["kind"].metadata["choices"]
    delays = _floats(args.delays, sc.delays_s, "delays")
    losses = _floats(args.losses, sc.losses, "losses")
    if any(p > 1 for p in losses):
        raise UserInputError("--losses: loss probabilities must be within [0, 1]")
    controllers = _names(args.controllers, sc.controllers, known)
    seed = cfg.session.seed if args.seed is None else args.seed
    duration = sc.duration_s if args.duration is None else args.duration
    jitter = sc.jitter_s if args.jitter is None else args.jitter
    workers = sc.workers if args.workers is None else args.workers
    refine = sc.refine_steps if args.refine is None else args.refine
    if workers < 0 or refine < 0 or (args.workers is not None and args.workers < 1):
        raise UserInputError("--jobs must be >= 1 and --refine >= 0")
    workers = workers or os.cpu_count() or 1
    if args.grid or args.endurance:
        if (args.rerun or args.delays or args.losses or args.refine is not None
                or args.jitter is not None):
            raise UserInputError("--grid/--endurance: --delays, --losses, --jitter, --refine "
                                 "and --rerun apply to the delay sweep only")
        return _run_special(args, cfg, controllers, seed, args.workers or sc.workers)
    if args.mode == "live":
        workers = 1  # real-time runs share the machine; one at a time keeps timing honest
    # the prediction needs no run, and no run needs it (only which controllers it names):
    # in lockstep it is worked out beside the runs; live runs keep the machine to themselves
    side = ThreadPoolExecutor(1) if args.mode == "lockstep" else None
    pending = side.submit(predicted_limits, cfg) if side is not None else None
    try:
        predicted, notes = predicted_limits(cfg) if pending is None else ((), ())
        runner = lockstep_runner if args.mode == "lockstep" else live_runner
        progress = _Progress(not args.no_progress)
        result = run_delay_sweep(cfg, delays, losses, controllers, args.mode, seed, duration,
                                 progress, runner=runner, jitter_s=jitter,
                                 workers=workers, refine_steps=refine,
                                 keep_signals=bool(args.rerun),
                                 refine_controllers=list(predicted_controllers(cfg)))
        progress.finish()
        if pending is not None:
            predicted, notes = pending.result()
    finally:
        if side is not None:
            side.shutdown()
    from dataclasses import replace

    result = replace(result, predicted_max_stable_delay_s=tuple(predicted),
                     notes=result.notes + notes)
    out = sys.stderr if args.json_path == "-" else sys.stdout
    print(format_table(result), file=out)
    print(f"{len(result.runs)} runs in {result.wall_s:.1f} s ({args.mode})", file=out)
    write_json(args.json_path, result.to_json())
    if args.plot and result.runs:
        from teleop.analysis.sweep_plot import plot_sweep

        print(f"plot: {plot_sweep(result, args.plot)}", file=out)
    if args.rerun and result.runs:
        from teleop.analysis.sweep_rerun import log_sweep

        print(f"rerun log: {log_sweep(result, args.rerun)}", file=out)
    return _status(result, args)
