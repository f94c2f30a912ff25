"""The bus interface the services use, and the receiver-side pipeline both buses share.

A bus is one service's view of the network: it publishes the signals its role sends and
receives the signals its role receives (see :mod:`teleop.transport.keys`).  Every received
message goes, at the receiver, through: arrival -> the link's delay line (delay, jitter,
loss, duplication, reordering; seeded) -> :class:`SafeDecoder` (bad messages are counted and
dropped) -> a sequence check (a ``seq`` not above the last accepted one is dropped and
counted as ``stale_seq``) -> :class:`Received`, with the achieved delay measured.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from teleop.config.transport import LinksConfig
from teleop.messages import Message
from teleop.transport.delay_line import (
    DelayLineState,
    DelayParams,
    Delivered,
    delay_line_pop_due,
    delay_line_push,
    delay_params,
    next_release_s,
)
from teleop.transport.keys import SIGNALS, check_role, signal_spec
from teleop.transport.safe_decoder import RejectCounts, SafeDecoder

_LINK_SALT = {"master_controller": 0, "controller_hand": 1}


@dataclass(frozen=True, slots=True)
class Received:
    """One message handed to the receiving service."""

    signal: str
    message: Message
    sent_t_s: float  # when the sender published it (sender's bus clock)
    received_t_s: float  # when receive() released it (receiver's bus clock)
    delay_s: float  # achieved one-way delay: received_t_s - sent_t_s


@dataclass(frozen=True, slots=True)
class LinkStats:
    """Counters of one received signal (one link direction) at the receiver."""

    signal: str
    arrived: int  # messages that reached the delay line
    lost: int  # dropped by the injected loss
    duplicated: int  # extra copies injected
    released: int  # left the delay line (decoded or rejected after)
    delivered: int  # handed to the service as Received
    mean_delay_s: float  # over released messages (nan if none)
    max_delay_s: float


@dataclass(frozen=True, slots=True)
class BusStats:
    """A frozen snapshot of one bus view's counters."""

    role: str
    rejects: RejectCounts  # decode failures and stale_seq, per reason
    links: tuple[LinkStats, ...]

    def link(self, signal: str) -> LinkStats:
        """The :class:`LinkStats` of ``signal`` (KeyError if this role does not receive it)."""
        for s in self.links:
            if s.signal == signal:
                return s
        raise KeyError(signal)


@runtime_checkable
class Bus(Protocol):
    """One service's connection to the others (in-process or zenoh)."""

    role: str

    def publish(self, signal: str, msg: Message) -> None:
        """Send ``msg`` on ``signal`` (this role must be the signal's sender)."""
        ...

    def receive(self, signal: str) -> list[Received]:
        """Messages on ``signal`` released since the last call, oldest release first."""
        ...

    def alive(self, role: str) -> bool:
        """Whether the service ``role`` is up (liveliness)."""
        ...

    def stats(self) -> BusStats:
        """Counters: rejections per reason and per-link delay-line figures."""
        ...

    def close(self) -> None:
        """Release everything (idempotent)."""
        ...


def link_params(links: LinksConfig, signal: str) -> DelayParams:
    """Delay-line params of the link direction ``signal`` travels on."""
    spec = signal_spec(signal)
    return delay_params(getattr(links, spec.link), spec.forward, _LINK_SALT[spec.link])


class Inbox:
    """Receiver side of one signal: delay line, safe decoding, stale-sequence filter."""

    def __init__(self, signal: str, links: LinksConfig, decoder: SafeDecoder,
                 drop_stale: bool = True) -> None:
        self.signal = signal
        self.spec = signal_spec(signal)
        self.params = link_params(links, signal)
        self.state = DelayLineState()
        self._decoder = decoder
        self._drop_stale = drop_stale
        self._last_seq: int | None = None
        self._delivered = 0

    def arrive(self, payload: bytes, t_s: float) -> None:
        """A message entered the link at ``t_s`` (its delay counts from there)."""
        self.state = delay_line_push(self.state, self.params, payload, t_s)

    def release(self, now_s: float) -> list[Received]:
        """Decode and return everything due at ``now_s``."""
        self.state, due = delay_line_pop_due(self.state, now_s)
        return self._deliver(due)

    def arrive_and_release(self, arrivals: Iterable[tuple[bytes, float]],
                           now_s: float) -> list[Received]:
        """:meth:`arrive` each ``(payload, t_s)`` then :meth:`release` at ``now_s``.

        Due messages are popped as they come so a large backlog does not pile up in the
        delay line (whose push is O(messages in flight)); the result is in release order.
        """
        due: list[Delivered] = []
        for payload, t_s in arrivals:
            self.state = delay_line_push(self.state, self.params, payload, t_s)
            pending = self.state.pending
            if pending and pending[0].release_t_s <= now_s:
                self.state, got = delay_line_pop_due(self.state, now_s)
                due += got
        self.state, got = delay_line_pop_due(self.state, now_s)
        due += got
        due.sort(key=lambda d: d.release_t_s)
        return self._deliver(due)

    def _deliver(self, due: list[Delivered]) -> list[Received]:
        out: list[Received] = []
        for d in due:
            msg = self._decoder.decode(d.payload, self.spec.msg_type)
            if msg is None:
                continue
            seq = msg.header.seq
            if self._drop_stale and self._last_seq is not None and seq <= self._last_seq:
                self._decoder.reject("stale_seq", f"{self.signal} seq {seq} <= {self._last_seq}")
                continue
            self._last_seq = seq
            out.append(Received(self.signal, msg, d.sent_t_s, d.delivered_t_s, d.delay_s))
        self._delivered += len(out)
        return out

    def reset_seq(self) -> None:
        """Forget the last sequence number (the sender restarted)."""
        self._last_seq = None

    def next_release_s(self) -> float | None:
        """When the next message is due, if any is in flight."""
        return next_release_s(self.state)

    def stats(self) -> LinkStats:
        """This signal's counters."""
        s = self.state
        mean = s.delay_sum_s / s.n_delivered if s.n_delivered else float("nan")
        return LinkStats(self.signal, s.n_pushed, s.n_lost, s.n_duplicated, s.n_delivered,
                         self._delivered, mean, s.delay_max_s)


def check_publish(role: str, signal: str, msg: Message) -> None:
    """Programming errors: a role publishing a signal it does not own, or a wrong type."""
    spec = signal_spec(signal)
    if spec.sender != role:
        raise ValueError(f"{role} cannot publish {signal!r} (sent by {spec.sender})")
    if type(msg) is not spec.msg_type:
        raise TypeError(f"{signal!r} carries {spec.msg_type.__name__}, "
                        f"got {type(msg).__name__}")


def make_inboxes(role: str, links: LinksConfig, decoder: SafeDecoder,
                 drop_stale: bool = True) -> dict[str, Inbox]:
    """One :class:`Inbox` per signal ``role`` receives."""
    check_role(role)
    return {name: Inbox(name, links, decoder, drop_stale)
            for name, spec in SIGNALS.items() if spec.receiver == role}


def check_receive(role: str, inboxes: dict[str, Inbox], signal: str) -> Inbox:
    """The inbox of ``signal``; ValueError if ``role`` does not receive it."""
    try:
        return inboxes[signal]
    except KeyError:
        spec = signal_spec(signal)
        raise ValueError(f"{role} does not receive {signal!r} "
                         f"(received by {spec.receiver})") from None
