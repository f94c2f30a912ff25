"""``teleop servo-emulator``: emulated MX-28 servos on a pseudo-terminal, moved by the finger model.

Prints the pty's path on the first line of stdout (then flushes), serves until Ctrl-C (exit 0)
or ``--duration``.  Point the dynamixel backend at it::

    teleop servo-emulator --link /tmp/reflex &
    teleop up --set hand.backend=dynamixel --set hand.dynamixel.port=/tmp/reflex
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from teleop.commands.common import (
    add_config_options,
    config_from_args,
    nonneg_float,
    positive_float,
    serve_until_stopped,
)
from teleop.errors import UserInputError

REALTIME_PRIORITY = 30  # above the services' loops (10, 20): hardware is not preempted


def _fraction(text: str) -> float:
    value = nonneg_float(text)
    if value > 1.0:
        raise argparse.ArgumentTypeError(f"{text!r} must be between 0 and 1")
    return value


def _int_list(text: str) -> tuple[int, ...]:
    try:
        return tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list of "
                                         "integers") from None


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``servo-emulator`` subcommand."""
    p = sub.add_parser("servo-emulator", help="emulated Dynamixel MX-28s on a pseudo-terminal",
                       description="Emulate up to four MX-28 servos (real control table, "
                       "packets, checksums, error bits) on a pty; the finger servos drive the "
                       "finger model.  IDs, protocol, inversion and the object come from "
                       "--config (hand.dynamixel, hand.sim.object) unless given here.")
    add_config_options(p)
    p.add_argument("--protocol", type=int, choices=(1, 2), default=None,
                   help="Dynamixel protocol (default: hand.dynamixel.protocol)")
    p.add_argument("--ids", type=_int_list, default=None, metavar="1,2,3,4",
                   help="servo IDs (default: hand.dynamixel.ids)")
    p.add_argument("--homes", type=_int_list, default=None, metavar="C1,C2,...",
                   help="raw position (counts) of each servo with its finger open (default 0)")
    p.add_argument("--physics", choices=("finger", "simple"), default="finger",
                   help="finger model (default) or the simple fallback servo model")
    p.add_argument("--effect", action="append", default=[], metavar="NAME=VALUE",
                   help="a physical effect of the emulated fingers, e.g. coulomb_friction=2 "
                   "(N of tendon force) or dead_time=0.1 (s); repeatable; --physics finger only")
    p.add_argument("--no-realtime", dest="realtime", action="store_false",
                   help="do not serve under SCHED_FIFO (default: try, above the services' 1 kHz "
                   "loops: the emulator stands in for hardware that a busy CPU cannot slow)")
    p.add_argument("--duration", type=positive_float, default=None, metavar="S",
                   help="stop after S seconds (default: run until Ctrl-C)")
    p.add_argument("--link", type=Path, default=None, metavar="PATH",
                   help="also make PATH a symlink to the pty (removed at exit)")
    p.add_argument("--return-delay-us", type=int, default=0, metavar="US",
                   help="servo return delay time (default 0)")
    f = p.add_argument_group("fault injection")
    f.add_argument("--drop-rate", type=_fraction, default=0.0, metavar="P",
                   help="probability of not sending a reply")
    f.add_argument("--corrupt-rate", type=_fraction, default=0.0, metavar="P",
                   help="probability of a reply with a wrong checksum/CRC")
    f.add_argument("--latency-ms", type=nonneg_float, default=0.0, metavar="MS",
                   help="extra delay before every reply")
    f.add_argument("--overload-id", type=int, action="append", default=[], metavar="ID",
                   help="servo reporting the overload error bit (repeatable)")
    f.add_argument("--overheat-id", type=int, action="append", default=[], metavar="ID",
                   help="servo reporting the overheat error bit (repeatable)")
    f.add_argument("--voltage-id", type=int, action="append", default=[], metavar="ID",
                   help="servo reporting the input voltage error bit (repeatable)")
    f.add_argument("--seed", type=int, default=0, help="seed of the fault draws")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Serve the emulated servos until Ctrl-C or ``--duration``."""
    from sim.servo_emulator_bus import FaultConfig
    from sim.servo_emulator_pty import PtyServoEmulator, make_bus_emulator
    from teleop.effects import parse_effects

    cfg = config_from_args(args)
    effects = parse_effects(args.effect)
    if effects.active() and args.physics != "finger":
        raise UserInputError(f"--effect {args.effect[0]}: needs --physics finger (the simple "
                             "fallback servo has no physical effects)")
    d = cfg.hand.dynamixel
    protocol = args.protocol or int(d.protocol)
    ids = args.ids if args.ids is not None else tuple(d.ids)
    if not 1 <= len(ids) <= 4 or len(set(ids)) != len(ids) or not all(0 <= i < 253 for i in ids):
        raise UserInputError(f"--ids: need 1 to 4 distinct IDs in 0..252, got {list(ids)}")
    homes = args.homes if args.homes is not None else (0,) * len(ids)
    if len(homes) != len(ids):
        raise UserInputError(f"--homes: need {len(ids)} values, got {len(homes)}")
    if not 0 <= args.return_delay_us <= 508:
        raise UserInputError("--return-delay-us must be in 0..508")
    for flag, fault_ids in (("--overload-id", args.overload_id),
                            ("--overheat-id", args.overheat_id),
                            ("--voltage-id", args.voltage_id)):
        unknown = [i for i in fault_ids if i not in ids]
        if unknown:
            raise UserInputError(f"{flag} {unknown[0]}: no emulated servo has that ID "
                                 f"(IDs: {','.join(map(str, ids))})")
    faults = FaultConfig(args.drop_rate, args.corrupt_rate, args.latency_ms / 1000.0,
                         tuple(args.overload_id), tuple(args.overheat_id), args.seed,
                         tuple(args.voltage_id))
    bus = make_bus_emulator(protocol, ids, tuple(d.inversion), homes, cfg.hand.sim.object,
                            faults, args.return_delay_us, args.physics, effects,
                            cfg.hand.sim.engine)
    if args.realtime:  # before the path is printed: a client may write at once
        from services.runtime import try_realtime_priority

        if not try_realtime_priority(REALTIME_PRIORITY):
            print("servo-emulator: no real-time priority (needs CAP_SYS_NICE); on a busy "
                  "machine replies may time out", file=sys.stderr, flush=True)
    emu = PtyServoEmulator(bus, cfg.hand.sim.physics_rate_hz)
    path = emu.open()
    link: Path | None = args.link
    if link is not None:
        if link.is_symlink():
            link.unlink()
        elif link.exists():
            emu.stop()
            raise UserInputError(f"--link {link}: exists and is not a symlink")
        try:
            os.symlink(path, link)
        except OSError as exc:
            emu.stop()
            raise UserInputError(f"--link {link}: cannot create ({exc.strerror})") from None
    print(path, flush=True)
    print(f"servo-emulator: {len(ids)} MX-28 (protocol {protocol}.0, IDs "
          f"{','.join(map(str, ids))}) on {link or path}; physics: {bus.physics.label}; "
          "Ctrl-C to stop", file=sys.stderr, flush=True)
    try:
        serve_until_stopped(lambda: emu.serve(args.duration))
    finally:
        emu.stop()
        if link is not None and link.is_symlink():
            link.unlink()
    c = bus.counters
    print(f"servo-emulator: {c.packets} packets, {c.replies} replies, {c.bad_checksums} bad "
          f"checksums received, {c.dropped} dropped, {c.corrupted} corrupted",
          file=sys.stderr, flush=True)
    return 0
