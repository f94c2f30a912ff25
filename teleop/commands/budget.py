"""``teleop budget``: where the joules go, grasp by grasp (physical audit beside the books).

Runs the whole loop in lockstep (virtual operator, controller, simulated hand) and prints per
grasp cycle the net work at the operator and object ports (from the simulated physics), the
controllers' port ledgers and the change of all stored energy.  Examples::

    teleop budget                                     # defaults, 27 s: six grasps
    teleop budget --set master.virtual.style=soft --seconds 60 --json -

Progress on stderr while it runs (``--no-progress`` for none); Ctrl-C ends the run at the
time reached and reports the grasps completed by then (exit 130), a second Ctrl-C at once.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import asdict

from teleop.commands.common import (
    FirstInterrupt,
    FractionProgress,
    add_config_options,
    add_json_option,
    config_from_args,
    positive_float,
    write_json,
)


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``budget`` subcommand."""
    p = sub.add_parser("budget", help="per-grasp energy budget: audit vs ledgers (lockstep)",
                       description=__doc__.splitlines()[0])
    add_config_options(p)
    add_json_option(p)
    p.add_argument("--seconds", type=positive_float, default=27.0,
                   help="virtual seconds to run (default 27: six grasps of the default script)")
    p.add_argument("--seed", type=int, default=1, help="run seed (default 1)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run the loop and print (and write) the budget."""
    cfg = config_from_args(args)
    from services.lockstep import run_lockstep
    from teleop.analysis.energy_budget import format_budget, grasp_budget

    cycle = cfg.master.virtual.cycle_s
    progress = FractionProgress(f"{args.seconds:g} simulated s (lockstep)",
                                not args.no_progress)
    with FirstInterrupt() as interrupted:
        r = run_lockstep(cfg, args.seconds, seed=args.seed, progress=progress,
                         stop=interrupted)
    progress.finish()
    rows = grasp_budget(r, cycle)
    if args.json_path != "-":
        print(format_budget(rows))
    write_json(args.json_path, {"controller": cfg.controller.kind, "cycle_s": cycle,
                                "seconds": r.duration_s, "interrupted": interrupted.asked,
                                "grasps": [asdict(b) for b in rows]})
    if interrupted.asked:
        print(f"teleop budget: interrupted at {r.duration_s:.1f} of {args.seconds:g} simulated "
              f"s; the {len(rows)} grasps completed by then are reported", file=sys.stderr)
        return 130
    return 0
