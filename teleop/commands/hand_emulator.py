"""``teleop hand-emulator``: an emulated ReFlex TakkTile brain board on loopback UDP.

Prints ``HOST:PORT`` on the first line of stdout (then flushes) and serves until Ctrl-C /
SIGTERM (exit 0) or ``--duration``; the counters go to stderr (and ``--json``).  Point the
``reflex-takktile`` backend at it::

    teleop hand-emulator --port 11333 &
    teleop up --set hand.backend=reflex-takktile --set hand.takktile.network=unicast \\
        --set hand.takktile.address=127.0.0.1
"""

from __future__ import annotations

import argparse
import ipaddress
import sys

from teleop.commands.common import (
    add_config_options,
    add_json_option,
    config_from_args,
    nonneg_float,
    positive_float,
    serve_until_stopped,
    write_json,
)
from teleop.commands.servo_emulator import _fraction, _int_list
from teleop.errors import UserInputError


def _stuck(text: str) -> tuple[int, int]:
    """``F:S`` or ``F:S=VALUE`` -> (tactile index, value or -1)."""
    where, _, value = text.partition("=")
    try:
        finger, sensor = (int(v) for v in where.split(":"))
        raw = int(value) if value else -1
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected FINGER:SENSOR[=VALUE], "
                                         "e.g. 1:3 or 2:7=900") from None
    if not (1 <= finger <= 3 and 1 <= sensor <= 9 and -1 <= raw <= 65535):
        raise argparse.ArgumentTypeError(f"{text!r}: finger 1-3, sensor 1-9, value 0-65535")
    return 9 * (finger - 1) + sensor - 1, raw


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``hand-emulator`` subcommand."""
    p = sub.add_parser("hand-emulator", help="emulated ReFlex TakkTile brain board on UDP",
                       description="Emulate the brain board (modes/targets in, 202-byte state "
                       "packets out at 40 Hz, 28 Hz while grasping); the physics is the "
                       "simulated hand with the object of hand.sim.object, so the tactile "
                       "pressures are model outputs.")
    add_config_options(p)
    add_json_option(p)
    p.add_argument("--address", default="127.0.0.1",
                   help="unicast: address to bind (default 127.0.0.1); multicast: the group")
    p.add_argument("--port", type=int, default=11333, help="UDP port (default 11333; 0 = any)")
    p.add_argument("--multicast", action="store_true",
                   help="join --address as a multicast group (224.0.0.124 on the real hand)")
    p.add_argument("--interface", default="", metavar="IP",
                   help="multicast: local interface address (default: the system's choice)")
    p.add_argument("--homes", type=_int_list, default=None, metavar="C1,C2,C3,C4",
                   help="raw servo position (counts) with the finger open (default 0,0,0,0)")
    p.add_argument("--load-noise", type=nonneg_float, default=8.0, metavar="UNITS",
                   help="standard deviation of the load estimate's noise (default 8)")
    p.add_argument("--overload-units", type=positive_float, default=1000.0, metavar="UNITS",
                   help="servo load that, held for --overload-s, trips the overload alarm "
                   "(error bit 5, torque off until modes are sent again; default 1000)")
    p.add_argument("--overload-s", type=nonneg_float, default=0.2, metavar="S",
                   help="how long the load must stay above --overload-units (default 0.2)")
    p.add_argument("--duration", type=positive_float, default=None, metavar="S",
                   help="stop after S seconds (default: run until Ctrl-C)")
    f = p.add_argument_group("fault injection (state packets)")
    f.add_argument("--loss", type=_fraction, default=0.0, metavar="P", help="lost packets")
    f.add_argument("--late-rate", type=_fraction, default=0.0, metavar="P",
                   help="packets held back by --late-ms (newer ones overtake them)")
    f.add_argument("--late-ms", type=nonneg_float, default=60.0, metavar="MS",
                   help="how late a late packet is (default 60)")
    f.add_argument("--truncate-rate", type=_fraction, default=0.0, metavar="P",
                   help="packets cut short")
    f.add_argument("--garble-rate", type=_fraction, default=0.0, metavar="P",
                   help="packets with 1-8 random bytes replaced")
    f.add_argument("--bad-magic-rate", type=_fraction, default=0.0, metavar="P",
                   help="packets with a wrong magic byte")
    f.add_argument("--stuck-sensor", type=_stuck, action="append", default=[],
                   metavar="F:S[=V]", help="tactile sensor S (1-9) of finger F (1-3) stuck at "
                   "V (default: its reading when the run starts); repeatable")
    f.add_argument("--silent-after", type=nonneg_float, default=None, metavar="S",
                   help="stop sending state packets S seconds after the first command")
    f.add_argument("--silent-for", type=positive_float, default=None, metavar="S",
                   help="and resume after S seconds of silence (default: never)")
    f.add_argument("--seed", type=int, default=0, help="seed of the noise and fault draws")
    p.set_defaults(run=run)


def _check(args: argparse.Namespace) -> None:
    try:
        ip = ipaddress.IPv4Address(args.address)
    except ValueError:
        raise UserInputError(f"--address {args.address!r}: not an IPv4 address") from None
    if args.multicast != ip.is_multicast:
        raise UserInputError(f"--address {args.address}: " + (
            "--multicast needs a multicast group (224.0.0.0/4), e.g. 224.0.0.124"
            if args.multicast else "is a multicast group: add --multicast"))
    if args.interface:
        try:
            ipaddress.IPv4Address(args.interface)
        except ValueError:
            raise UserInputError(f"--interface {args.interface!r}: not an IPv4 address") \
                from None
    if not 0 <= args.port <= 65535:
        raise UserInputError(f"--port {args.port}: must be in 0..65535")
    if args.homes is not None and len(args.homes) != 4:
        raise UserInputError(f"--homes: need 4 values, got {len(args.homes)}")
    if args.silent_for is not None and args.silent_after is None:
        raise UserInputError("--silent-for needs --silent-after")


def run(args: argparse.Namespace) -> int:
    """Serve the emulated board until Ctrl-C / SIGTERM or ``--duration``."""
    _check(args)
    cfg = config_from_args(args)
    from sim.hand_emulator import BoardParams, BrainBoardModel
    from sim.hand_emulator_faults import BoardFaults
    from sim.hand_emulator_udp import UdpBrainBoard

    d = cfg.hand.dynamixel
    params = BoardParams(homes_counts=tuple(args.homes or (0, 0, 0, 0)),  # type: ignore[arg-type]
                         inversion=tuple(d.inversion),  # type: ignore[arg-type]
                         finger_ratio=d.finger_ratio, preshape_ratio=d.preshape_ratio,
                         load_noise_units=args.load_noise, overload_units=args.overload_units,
                         overload_s=args.overload_s, seed=args.seed)
    faults = BoardFaults(args.loss, args.late_rate, args.late_ms / 1000.0, args.truncate_rate,
                         args.garble_rate, args.bad_magic_rate, tuple(args.stuck_sensor),
                         args.silent_after, args.silent_for, args.seed)
    board = UdpBrainBoard(BrainBoardModel(cfg.hand, params), faults, args.address, args.port,
                          args.multicast, args.interface)
    board.model.start()  # the physics engine compiled or loaded before the address is out
    try:
        host, port = board.open()
    except OSError as exc:
        raise UserInputError(f"--address {args.address} --port {args.port}: cannot bind "
                             f"({exc.strerror})") from None
    out = sys.stderr if args.json_path == "-" else sys.stdout
    print(f"{host}:{port}", file=out, flush=True)
    print(f"hand-emulator: brain board on {'multicast' if args.multicast else 'unicast'} "
          f"{host}:{port}; object {cfg.hand.sim.object.kind}; Ctrl-C to stop",
          file=sys.stderr, flush=True)
    try:
        serve_until_stopped(lambda: board.serve(args.duration))
    finally:
        board.close()
    summary = board.summary()
    print(f"hand-emulator: {summary['states']} states, {summary['sent']} sent, "
          f"{summary['commands']} commands, faults {summary['faults']}, bad commands "
          f"{summary['bad_commands']}", file=sys.stderr, flush=True)
    write_json(args.json_path, summary)
    return 0
