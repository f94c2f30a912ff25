"""``teleop run master|controller|hand``: one service, for running on separate machines.

Examples::

    # machine B (next to the hand, 10.0.0.2): controller listening, hand beside it
    teleop run controller --set zenoh.endpoint=tcp/0.0.0.0:7447 --set zenoh.shared_clock=false
    teleop run hand --set zenoh.endpoint=tcp/127.0.0.1:7447 --set zenoh.shared_clock=false
    # machine A (the operator's desk): the master, connecting to the controller
    teleop run master --set zenoh.endpoint=tcp/10.0.0.2:7447 --set zenoh.shared_clock=false

The service prints ``ready <role>`` when its bus is up, then runs until Ctrl-C (or
``--duration``).  ``teleop up`` starts three of these as child processes.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from teleop.commands.common import (
    add_config_options,
    check_output_path,
    config_from_args,
    nonneg_float,
)
from teleop.errors import UserInputError

ROLES = ("master", "controller", "hand")


def add_dashboard_option(p: argparse.ArgumentParser, default: str | None) -> None:
    """``--dashboard spawn|web|save:PATH|off`` (plus ``connect:URL`` for a running viewer)."""
    p.add_argument("--dashboard", default=default, metavar="MODE",
                   help="spawn | web | save:PATH | connect:URL | off (teleop up: default spawn a "
                   "viewer when there is a display, else save to dashboard.path; teleop run: "
                   "default off)")


def add_realtime_option(p: argparse.ArgumentParser) -> None:
    """``--no-realtime``: do not ask for SCHED_FIFO for the 1 kHz loops."""
    p.add_argument("--no-realtime", dest="realtime", action="store_false",
                   help="do not run 1 kHz loops under SCHED_FIFO (default: try, fall back)")


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``run`` subcommand."""
    p = sub.add_parser("run", help="run one service (master, controller or hand)",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("role", choices=ROLES, help="which service")
    add_config_options(p)
    p.add_argument("--duration", type=nonneg_float, default=None, metavar="S",
                   help="stop after S seconds (default: until Ctrl-C)")
    add_dashboard_option(p, default="off")
    p.add_argument("--record", default=None, metavar="DIR",
                   help="write this service's signals to DIR/<role>.csv")
    p.add_argument("--recording-id", default=None, metavar="ID",
                   help="rerun recording id shared by the services of one session")
    p.add_argument("--epoch", type=float, default=None, metavar="T",
                   help="monotonic time the session started (dashboard time origin)")
    p.add_argument("--wait-peers", type=nonneg_float, default=None, metavar="S",
                   help="give up if the peers are not alive after S seconds (default: wait)")
    add_realtime_option(p)
    p.add_argument("--watch-stdin", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--stats-json", default=None, help=argparse.SUPPRESS)
    p.add_argument("--soak-log", default=None, help=argparse.SUPPRESS)  # teleop faults --soak
    p.set_defaults(run=run)


def check_service_dashboard(text: str) -> None:
    """One line (exit 2) for a ``--dashboard`` a service cannot use, before anything starts."""
    mode, sep, arg = text.partition(":")
    if mode == "save" and sep and arg:
        check_output_path(arg, "the dashboard recording")
    elif not ((mode in ("off", "spawn", "web") and not sep) or mode == "connect"):
        raise UserInputError(f"--dashboard {text!r}: expected spawn, web, save:PATH, "
                             "connect:URL or off")


def run(args: argparse.Namespace) -> int:
    """Run the service until stopped."""
    from services.process import ServiceOptions, run_service

    cfg = config_from_args(args)
    check_service_dashboard(args.dashboard or "off")
    if args.record is not None:  # the recording opens at the first row: fail before the wait
        check_output_path(Path(args.record) / f"{args.role}.csv", "recordings")
    opts = ServiceOptions(role=args.role, duration_s=args.duration,
                          dashboard=args.dashboard or "off", record_dir=args.record,
                          recording_id=args.recording_id, epoch_s=args.epoch,
                          watch_stdin=args.watch_stdin, stats_path=args.stats_json,
                          peer_timeout_s=args.wait_peers, realtime=args.realtime,
                          soak_dir=args.soak_log)
    return run_service(cfg, opts)
