"""``teleop bench NAME``: benchmarks, one flat JSON object of figures (units in the keys).

Each benchmark is a ``"module:function"`` in :data:`BENCHES`, imported only when run; the
function takes no arguments and returns a flat ``dict`` of figures.

Example::

    teleop bench transport --json -
"""

from __future__ import annotations

import argparse
import importlib
from collections.abc import Callable
from typing import Any

from teleop.commands.common import add_json_option, info, write_json
from teleop.errors import UserInputError

#: Benchmark name -> "module:function" (lazily imported).
BENCHES: dict[str, str] = {
    "transport": "teleop.transport.bench:bench_transport",
    "sim": "sim.bench:bench_sim",
    "loop": "services.bench:bench_loop",
    "dashboard": "services.bench_dashboard:bench_dashboard",
    "lockstep": "services.bench_lockstep:bench_lockstep",
    "servo": "sim.servo_emulator_bench:bench_servo",
    "takktile": "sim.hand_emulator_bench:bench_takktile",
    "diagnose": "teleop.diagnose.bench:bench_diagnose",
    "diagnose-finger": "sim.finger_diagnose_bench:bench_diagnose_finger",
}


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``bench`` subcommand."""
    p = sub.add_parser("bench", help="run a benchmark (JSON figures)")
    p.add_argument("name", help="benchmark: " + ", ".join(sorted(BENCHES)))
    add_json_option(p)
    p.add_argument("--reference", default=None, metavar="DIR",
                   help="lockstep and dashboard: a source tree of an earlier implementation "
                   "(e.g. `git archive REV | tar -x -C DIR`), run side by side with this one")
    p.add_argument("--repeats", type=int, default=None, metavar="N",
                   help="lockstep and dashboard: alternations of this tree and the reference "
                   "(lockstep: best of N each; dashboard: median; default 2)")
    p.add_argument("--instructions", action="store_true",
                   help="lockstep only: also count the machine instructions of one simulated "
                   "second in this tree and the reference (valgrind's callgrind; load-"
                   "independent; the first run compiles for valgrind's CPU, minutes)")
    p.set_defaults(run=run)


def _load(name: str) -> Callable[[], dict[str, Any]]:
    try:
        target = BENCHES[name]
    except KeyError:
        raise UserInputError(f"unknown benchmark {name!r} (known: "
                             f"{', '.join(sorted(BENCHES))})") from None
    module, func = target.split(":")
    return getattr(importlib.import_module(module), func)  # type: ignore[no-any-return]


def run(args: argparse.Namespace) -> int:
    """Run one benchmark and print/write its figures."""
    fn = _load(args.name)
    kwargs: dict[str, Any] = {}
    side_by_side = ("lockstep", "dashboard")
    if getattr(args, "reference", None) is not None:
        if args.name not in side_by_side:
            raise UserInputError(f"--reference: only for `bench lockstep` and `bench "
                                 f"dashboard`, not {args.name!r}")
        from services.bench_lockstep import check_reference

        kwargs["reference"] = str(check_reference(args.reference))
    if getattr(args, "repeats", None) is not None:
        if args.name not in side_by_side or args.repeats < 1:
            raise UserInputError("--repeats: a count >= 1, only for `bench lockstep` and "
                                 "`bench dashboard`")
        kwargs["repeats"] = args.repeats
    if getattr(args, "instructions", False):
        if args.name != "lockstep":
            raise UserInputError(f"--instructions: only for `bench lockstep`, not "
                                 f"{args.name!r}")
        kwargs["instructions"] = True
    info(args, f"bench {args.name}: running...")
    figures = fn(**kwargs)
    if args.json_path is None:
        for key, value in figures.items():
            print(f"{key}: {value:.6g}" if isinstance(value, float) else f"{key}: {value}")
    write_json(args.json_path, figures)
    return 0
