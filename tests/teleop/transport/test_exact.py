"""The in-process bus passes a message object only when the codec round-trips it exactly.

Held against the codec itself, not against the predicate's own reasoning: every message
:func:`round_trips` accepts decodes from its encoding to an equal copy with the same type in
every field; every mutation the argument rests on (a float that is an int, a numpy float, a
list for a tuple, out of range, NaN, a bool seq, an int mode) is refused, and the checked path
then either rejects it or gives back something of another type."""

from __future__ import annotations

import dataclasses
import math
import random

import numpy as np
import pytest

from teleop.config import load_config
from teleop.errors import DecodeError
from teleop.messages import (
    FingerState,
    ForceCommand,
    HandCommand,
    HandMode,
    HandState,
    Header,
    MasterState,
    Message,
)
from teleop.transport.clock import VirtualClock
from teleop.transport.codec import decode, encode
from teleop.transport.exact import round_trips
from teleop.transport.inproc_bus import InProcessHub


def _typed(x: object) -> object:
    """``x`` with the type of every leaf spelled out (equality alone ignores 1 == 1.0)."""
    if dataclasses.is_dataclass(x):
        return (type(x), tuple(_typed(getattr(x, f.name)) for f in dataclasses.fields(x)))
    if isinstance(x, tuple | list):
        return (type(x), tuple(_typed(v) for v in x))
    return (type(x), x)


def _random_messages(rng: random.Random, n: int) -> list[Message]:
    def u(lo: float, hi: float) -> float:
        return rng.uniform(lo, hi)

    def h() -> Header:
        return Header(rng.randrange(0, 2**40), u(0.0, 1e4), u(0.0, 50.0))

    def finger() -> FingerState:
        return FingerState(u(-1, 3), u(0, 2), u(-1, 3), u(-1000, 1000),
                           tuple(u(-10, 5000) for _ in range(9)),
                           tuple(rng.random() < 0.5 for _ in range(9)))

    def model(k: float) -> tuple[float, ...]:
        return tuple(v for _ in range(3) for v in (u(-1, 3), u(0, k)))

    out: list[Message] = []
    for _ in range(n):
        out += [MasterState(h(), u(-0.01, 0.05), u(-10, 10), u(-1, 1e4), u(0, 10)),
                ForceCommand(h(), u(-100, 100), model(1e4)),
                HandCommand(h(), (u(-1, 3), u(-1, 3), u(-1, 3)), u(-3, 3),
                            rng.choice(list(HandMode)), (u(-4096, 4096),) * 3),
                HandState(h(), (finger(), finger(), finger()), u(-3, 3), u(-1, 1e4),
                          u(0, 10), model(1e6), rng.randrange(0, 100), rng.random() < 0.5)]
    return out


def test_every_accepted_message_decodes_to_an_identical_copy() -> None:
    msgs = _random_messages(random.Random(7), 200)
    for m in msgs:
        assert round_trips(m), m
        assert _typed(decode(encode(m), type(m))) == _typed(m)


H = Header(seq=3, t_s=0.5, energy_total_j=0.1)
FINGER = FingerState(0.3, 0.1, 0.4, 10.0, (1.0,) * 9, (False,) * 9)
HS = HandState(H, (FINGER,) * 3, 0.2, contact_model=(0.1, 5.0) * 3)
MUTANTS: list[tuple[str, Message]] = [
    ("int float", MasterState(H, 0, 0.0)),  # type: ignore[arg-type]
    ("numpy float", MasterState(H, np.float64(0.01), 0.0)),  # type: ignore[arg-type]
    ("out of range", MasterState(H, 0.5, 0.0)),
    ("nan", MasterState(H, math.nan, 0.0)),
    ("bool seq", MasterState(Header(True, 0.5, 0.1), 0.01, 0.0)),  # type: ignore[arg-type]
    ("negative energy", MasterState(Header(3, 0.5, -1.0), 0.01, 0.0)),
    ("old version", MasterState(Header(3, 0.5, 0.1, version=0), 0.01, 0.0)),
    ("list setpoints", HandCommand(H, [0.1, 0.2, 0.3], 0.0)),  # type: ignore[arg-type]
    ("int mode", HandCommand(H, (0.1, 0.2, 0.3), 0.0, 1)),  # type: ignore[arg-type]
    ("short model", ForceCommand(H, 1.0, (0.1, 5.0))),
    ("negative stiffness", ForceCommand(H, 1.0, (0.1, -5.0) * 3)),
    ("model angle out of range", ForceCommand(H, 1.0, (0.1, 5.0, 9.0, 5.0, 0.1, 5.0))),
    ("int pressure", dataclasses.replace(HS, fingers=(FINGER, dataclasses.replace(
        FINGER, pressure=(1,) * 9), FINGER))),  # type: ignore[arg-type]
    ("int contact", dataclasses.replace(HS, fingers=(FINGER, dataclasses.replace(
        FINGER, contact=(0,) * 9), FINGER))),  # type: ignore[arg-type]
    ("bool trips", dataclasses.replace(HS, servo_fault_trips=True)),
    ("int safe flag", dataclasses.replace(HS, servo_safe=0)),  # type: ignore[arg-type]
    ("two fingers", dataclasses.replace(HS, fingers=(FINGER, FINGER))),  # type: ignore[arg-type]
]


@pytest.mark.parametrize(("what", "msg"), MUTANTS, ids=[w for w, _ in MUTANTS])
def test_what_the_codec_would_change_or_reject_is_refused(what: str, msg: Message) -> None:
    assert round_trips(HS) and not round_trips(msg), what
    try:
        back = decode(encode(msg), type(msg))
    except (DecodeError, TypeError, ValueError):
        return  # rejected (or not even encodable): must not bypass the checked path
    assert _typed(back) != _typed(msg), what  # decoded, but not the same object


def test_the_inproc_bus_passes_exact_messages_and_checks_the_rest() -> None:
    clock = VirtualClock(0.0)
    hub = InProcessHub(load_config(None, []).links, clock)
    master, ctrl = hub.bus("master"), hub.bus("controller")
    ok = MasterState(Header(1, 0.0, 0.1), 0.01, 0.0)
    bad = MasterState(Header(2, 0.0, 0.2), 0.5, 0.0)  # out of range: rejected by decode
    master.publish("master_state", ok)
    master.publish("master_state", bad)
    ctrl.inject("master_state", MasterState(Header(3, 0.0, 0.3), 0.5, 0.0))  # type: ignore[arg-type]
    clock.advance(1.0)
    got = [r.message for r in ctrl.receive("master_state")]
    assert got == [ok] and got[0] is ok
    counts = ctrl.stats().rejects
    assert counts.accepted == 1 and counts.count("out_of_range") == 2
