"""``teleop grasps DIR``: a recorded run judged grasp by grasp (does the loop keep working?).

Reads what ``teleop up --record DIR`` wrote and prints every grasp of the operator against
the first (peak pressure, closure as the fingers' curl held 0.1 s, felt force), how long each
energy store (master tank, hand tank, controller store) sat empty while the trigger was
closed, and how long each safety guard was active.  Examples::

    teleop up --duration 600 --dashboard off --record runs/a
    teleop grasps runs/a
    teleop grasps runs/a --every 10 --json runs/a/grasps.json --floor 0.9

The three recordings are read on one clock, as ``teleop up`` writes them; recordings of
services on separate machines (``zenoh.shared_clock=false``) each count from their own start
and are not aligned here.

With the virtual operator and the simulated hand the run is also audited by the physics:
the work done at the trigger and on the object against the tanks' initial energy (not the
controllers' books); the exit status is 1 when it shows energy created.

With ``--floor R`` the exit status is 1 when a grasp falls below R of the first by pressure,
closure or felt force, or a store sat empty for longer than ``--max-empty-s`` at a stretch.
"""

from __future__ import annotations

import argparse

from teleop.commands.common import add_json_option, info, nonneg_float, positive_float, write_json


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``grasps`` subcommand."""
    p = sub.add_parser("grasps", help="a recorded run (teleop up --record) judged grasp by "
                       "grasp: each against the first, empty tanks, guards",
                       description=__doc__.splitlines()[0])
    p.add_argument("dir", metavar="DIR", help="the directory of teleop up --record DIR")
    add_json_option(p)
    p.add_argument("--threshold-m", type=positive_float, default=None,
                   help="trigger closing (m) that starts a grasp (default: what the master "
                   "recorded, else a tenth of the default script's closing)")
    p.add_argument("--empty-j", type=positive_float, default=None,
                   help="a store below this is empty (default 0.005 J)")
    p.add_argument("--every", type=int, default=1, metavar="N",
                   help="print every N-th grasp (and always the weakest and the last)")
    p.add_argument("--floor", type=positive_float, default=None, metavar="R",
                   help="exit 1 when a grasp is below R of the first (pressure, closure, felt)")
    p.add_argument("--max-empty-s", type=nonneg_float, default=1.5,
                   help="with --floor: longest tolerated empty stretch of a store while the "
                   "trigger is closed (default 1.5 s: the start-up before the first touch)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Judge the run, print (and write) the report."""
    from teleop.analysis.grasps import grasp_threshold_m
    from teleop.analysis.recorded_run import (
        EMPTY_FLOOR_J,
        format_recorded_run,
        judge_recorded_run,
        read_run_dir,
    )
    from teleop.config import load_config
    from teleop.errors import RecordingError, UserInputError

    if args.every < 1:
        raise UserInputError(f"--every {args.every}: must be 1 or more")
    run_recs = read_run_dir(args.dir)
    threshold = args.threshold_m
    if threshold is None:
        text = run_recs.master.meta_value("grasp_threshold_m")
        try:
            threshold = float(text) if text is not None else grasp_threshold_m(load_config())
        except ValueError:
            raise RecordingError(f"{run_recs.master.source}: grasp_threshold_m {text!r} is "
                                 "not a number (give --threshold-m)") from None
    for name in ("trigger_position_m", "displayed_force_n", "tank_j"):
        run_recs.master.column(name)  # one line naming the file and column when missing
    report = judge_recorded_run(run_recs, threshold, args.empty_j or EMPTY_FLOOR_J)
    if args.json_path != "-":
        info(args, format_recorded_run(report, args.every))
    write_json(args.json_path, report.as_dict())
    if report.audit is not None and not report.audit.passive:
        info(args, f"FAIL: the physics shows energy created ({report.audit.generated_j:.4f} J "
             f"at {report.audit.min_at_s:.1f} s): the loop was not passive")
        return 1
    if args.floor is None:
        return 0
    g = report.judged  # a grasp a recording gap interrupted is listed, not judged
    weak = [x.index for x in g.grasps
            if min(x.pressure_ratio, x.closure_ratio, x.felt_ratio) < args.floor]
    starved = [e.store for e in report.empty if e.longest_s > args.max_empty_s]
    if not g.grasps:
        info(args, "FAIL: no complete grasp without a recording gap")
        return 1
    if weak or starved:
        k = report.reference_index
        ref = "the first" if k == 0 else f"grasp {k} (the first without a recording gap)"
        info(args, f"FAIL: {len(weak)} grasps below {args.floor:g} of {ref} {weak[:10]}; "
             f"stores empty longer than {args.max_empty_s:g} s: {starved}")
        return 1
    return 0
