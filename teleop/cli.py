"""The ``teleop`` command line: a thin dispatcher over one module per subcommand.

Each module in :mod:`teleop.commands` defines ``register(subparsers)``, which adds its parser
and sets ``run=<function(args) -> int>``.  Heavy imports happen inside ``run`` so that
``teleop --help`` stays fast.  User mistakes (:class:`~teleop.errors.UserInputError`) are
printed as one line on stderr with exit status 2.

Examples::

    teleop up --duration 10 --dashboard save:run.rrd --record runs/1
    teleop sim weight --force-n 9.8 --json -
    teleop sweep --json sweep.json --plot sweep.png
    teleop diagnose rec.csv --model axis --input torque_nm --output angle_rad
"""

from __future__ import annotations

import argparse
import importlib
import signal
import sys
from collections.abc import Sequence
from typing import NoReturn

from teleop.commands.common import check_outputs
from teleop.errors import DeviceError, UserInputError

#: Subcommand modules, in the order ``teleop --help`` lists them.
COMMAND_MODULES: tuple[str, ...] = (
    "up", "run", "sim", "sweep", "diagnose", "servo_emulator", "hand_emulator", "bench", "certs",
    "config", "faults", "budget", "grasps", "watch",
)


class _Parser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are one line and exit status 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    """The full ``teleop`` argument parser."""
    parser = _Parser(prog="teleop", description="Delayed, passive teleoperation of a ReFlex "
                     "TakkTile hand from a haptic grasp trigger.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(f"teleop.commands.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"teleop.commands.{name}":
                continue  # a subcommand not built yet
            raise
        module.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``teleop`` with ``argv``; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(list(argv) if argv is not None else None)
    try:
        check_outputs(args)  # before any work: results are never computed and then lost
        return int(args.run(args) or 0)
    except UserInputError as exc:
        print(f"teleop {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except DeviceError as exc:
        print(f"teleop {args.command}: device error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"teleop {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0


def entry() -> NoReturn:
    """Console-script entry point.  Ctrl-C (SIGINT) always stops ``teleop``: a shell script
    that starts it in the background (``teleop up &``) hands it SIGINT ignored, and Python
    then never raises KeyboardInterrupt, so ``kill -INT`` (and ``teleop up`` stopping its
    services the same way) would do nothing."""
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    sys.exit(main())


if __name__ == "__main__":
    entry()
