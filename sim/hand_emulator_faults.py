"""Fault injection for the emulated brain board's state packets (pure, seeded).

Each state packet, in this order: dropped while the board is silent (from ``silent_after_s``
after the first command, for ``silent_for_s``), lost (``loss``), its magic byte made wrong
(``bad_magic_rate``), truncated to a random shorter length (``truncate_rate``), some of its
bytes garbled (``garble_rate``: 1-8 random bytes replaced), held back by ``late_s`` so that
newer packets overtake it (``late_rate``).  A stuck sensor reads one value whatever the
physics does.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, replace

from teleop.devices.brain_board_packets import BoardState, encode_state


@dataclass(frozen=True, slots=True)
class BoardFaults:
    """What goes wrong with the board's state packets (rates are probabilities)."""

    loss: float = 0.0
    late_rate: float = 0.0
    late_s: float = 0.06
    truncate_rate: float = 0.0
    garble_rate: float = 0.0
    bad_magic_rate: float = 0.0
    #: (tactile index 0..37, value or -1 = its value when the fault began)
    stuck: tuple[tuple[int, int], ...] = ()
    silent_after_s: float | None = None
    silent_for_s: float | None = None  # None: silent for good
    seed: int = 0


@dataclass(frozen=True, slots=True)
class Outgoing:
    """One datagram to send ``delay_s`` after now."""

    delay_s: float
    data: bytes


def silent(f: BoardFaults, t_s: float) -> bool:
    """Whether the board sends nothing ``t_s`` after the first command (negative: none yet)."""
    if f.silent_after_s is None or t_s < f.silent_after_s:
        return False
    return f.silent_for_s is None or t_s < f.silent_after_s + f.silent_for_s


def stick(state: BoardState, f: BoardFaults, held: dict[int, int]) -> BoardState:
    """``state`` with the stuck sensors' readings held (``held`` remembers the -1 ones)."""
    if not f.stuck:
        return state
    p = list(state.pressures)
    for index, value in f.stuck:
        p[index] = held.setdefault(index, p[index] if value < 0 else value)
    return replace(state, pressures=tuple(p))


def faulty(data: bytes, f: BoardFaults, rng: random.Random,
           counts: dict[str, int]) -> list[Outgoing]:
    """What actually leaves for one encoded state packet (``counts`` by fault kind)."""
    def hit(kind: str, rate: float) -> bool:
        if rate > 0.0 and rng.random() < rate:
            counts[kind] = counts.get(kind, 0) + 1
            return True
        return False

    if hit("lost", f.loss):
        return []
    b = bytearray(data)
    if hit("bad_magic", f.bad_magic_rate):
        b[0] = rng.choice([v for v in range(256) if v != 1])
    if hit("truncated", f.truncate_rate):
        b = b[:rng.randrange(len(b))]
    if hit("garbled", f.garble_rate) and b:
        for _ in range(rng.randint(1, 8)):
            b[rng.randrange(len(b))] = rng.randrange(256)
    delay = f.late_s if hit("late", f.late_rate) else 0.0
    return [Outgoing(delay, bytes(b))]


def encode_with_faults(state: BoardState, t_s: float, f: BoardFaults, rng: random.Random,
                       held: dict[int, int], counts: dict[str, int]) -> list[Outgoing]:
    """The datagrams the faulty board sends for ``state``, ``t_s`` after the first command."""
    if silent(f, t_s):
        counts["silent"] = counts.get("silent", 0) + 1
        return []
    return faulty(encode_state(stick(state, f, held)), f, rng, counts)
