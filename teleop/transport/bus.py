"""The bus interface the services use, and the receiver-side pipeline both buses share.

A bus is one service's view of the network: it publishes the signals its role sends and
receives the signals its role receives (see :mod:`teleop.transport.keys`).  Every received
message goes, at the receiver, through: arrival -> the link's delay line (delay, jitter,
loss, duplication, reordering; seeded) -> :class:`SafeDecoder` (bad messages are counted and
dropped) -> a sequence check (a ``seq`` not above the last accepted one is dropped and
counted as ``stale_seq``; one more than ``seq_jump_max`` above it is dropped and counted as
``seq_jump``) -> an energy-total check (a cumulative ``energy_total_j`` below the
last accepted one is ``energy_decrease``, one above it by more than ``energy_jump_max_j`` is
``energy_jump``; both dropped) -> :class:`Received`, with the achieved delay measured.

Sender epochs: when a sender restarts (its liveliness token comes back), the receiver calls
:meth:`Inbox.reset_seq`: the sequence filter forgets the old numbering and the energy check
starts a new epoch.  The restarted sender counts its energy total from zero again; the inbox
presents it to the service shifted by the last total it handed on, so the total the control
layer sees stays monotone across restarts (its ``receive_total`` credits exactly the new
sender's increments, never the old sender's energy twice).  Only a sender's very first
message (``seq`` <= :data:`FIRST_SEQ`) is credited from zero; the first message of an epoch
that is not (a receiver that restarted or joined a running sender, whose predecessor may
already have credited that energy) is taken as the epoch's baseline and credits nothing:
the channel may lose energy, never create it.

After an outage (a cut link, a long burst of loss) a live sender's total has legitimately
grown by more than the cap.  So a jump is rejected, but :data:`JUMP_REBASE_COUNT`
consecutive jump rejections that are consistent among themselves (rising ``seq`` within
:data:`REBASE_MAX_SEQ_GAP` of the last accepted one, totals rising by at most the cap from
one to the next) re-baseline the epoch at the last one, which is accepted crediting nothing
of the jump (the energy sent into the outage is lost, never created).  A forged total cannot
do that: the sender's next genuine message is accepted and clears the run, and a forged
``seq`` far ahead (which would also shut the genuine sender out as stale) never qualifies.

Sequence jumps: a well-formed message whose ``seq`` is more than ``seq_jump_max`` above the
last accepted one is rejected as ``seq_jump`` (as ``energy_jump``/``energy_decrease`` when its
total would fail the energy check too) and does not move the filter, so one forged ``seq``
far ahead cannot make the genuine sender's later messages look stale.  A genuine
sender whose numbering really ran ahead (an outage longer than ``seq_jump_max`` messages
with its liveliness token kept) is re-synchronised: a run of at least
:data:`JUMP_REBASE_COUNT` jump rejections, each above the previous by at most
``seq_jump_max``, spanning :data:`SEQ_REBASE_MIN_S` of receive time with no message accepted
in between, moves the filter to the run.  A forger cannot do that while the genuine sender
is heard: its next accepted message clears the run.  A restarted sender does not need it:
its new epoch (liveliness) resets the filter, so it is accepted from its first ``seq``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Protocol, runtime_checkable

from teleop.config.transport import LinksConfig
from teleop.frozen import fast_init
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
from teleop.transport.fast_line import Due, FastLine, fast_params
from teleop.transport.keys import SIGNALS, check_role, signal_spec
from teleop.transport.safe_decoder import RejectCounts, SafeDecoder

_LINK_SALT = {"master_controller": 0, "controller_hand": 1}

#: Sequence number of a sender's first message (every service counts from 1).
FIRST_SEQ = 1
#: Consistent energy-jump rejections in a row after which the epoch is re-baselined.
JUMP_REBASE_COUNT = 3
#: Largest ``seq`` advance over the last accepted message that may re-baseline (an outage of
#: 100 s at 1 kHz).
REBASE_MAX_SEQ_GAP = 100_000
#: Receive time a run of ``seq_jump`` rejections must span before it re-synchronises the
#: sequence filter (a genuine sender's messages arrive all along it; a burst of forged ones
#: does not, and a genuine message in between clears the run).
SEQ_REBASE_MIN_S = 0.25


@fast_init
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
    rejects: RejectCounts  # decode failures, stale_seq, seq_jump, energy checks, per reason
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
    """Receiver side of one signal: delay line, safe decoding, sequence and energy checks.

    ``seq_jump_max``: largest accepted advance of ``seq`` over the last accepted message
    (None: unlimited); only with ``drop_stale``.
    """

    def __init__(self, signal: str, links: LinksConfig, decoder: SafeDecoder,
                 drop_stale: bool = True, energy_jump_max_j: float = math.inf,
                 seq_jump_max: int | None = None) -> None:
        self.signal = signal
        self.spec = signal_spec(signal)
        self._line: FastLine | None = None
        self._state = DelayLineState()
        self.params = link_params(links, signal)
        self._decoder = decoder
        self._drop_stale = drop_stale
        self._last_seq: int | None = None
        self._delivered = 0
        self.energy_jump_max_j = energy_jump_max_j
        self._epoch_energy_j: float | None = None  # last raw total accepted in this epoch
        self._energy_offset_j = 0.0  # added to this epoch's raw totals when handed on
        self._presented_energy_j = 0.0  # last total handed to the service
        self.epochs = 0  # sender restarts seen (reset_seq calls)
        self.rebases = 0  # epochs re-baselined after an outage
        self._jumps: list[tuple[int, float]] = []  # consecutive jump rejections (seq, total)
        self.seq_jump_max = seq_jump_max
        self.seq_rebases = 0  # sequence filter re-synchronised after a long outage
        self._seq_jumps: list[tuple[int, float]] = []  # consecutive seq_jump rejections (seq, t)

    @property
    def params(self) -> DelayParams:
        """The link direction's impairments (settable: a fault changes them)."""
        return self._params

    @params.setter
    def params(self, p: DelayParams) -> None:
        state = self.state
        self._params = p
        self.state = state  # on the mutable line when ``p`` allows it

    @property
    def state(self) -> DelayLineState:
        """The delay line's state (pure form; see :mod:`teleop.transport.fast_line`)."""
        return self._line.state() if self._line is not None else self._state

    @state.setter
    def state(self, s: DelayLineState) -> None:
        self._state = s
        self._line = FastLine.of(s) if fast_params(self._params) else None

    def arrive(self, payload: bytes | Message, t_s: float) -> None:
        """A message entered the link at ``t_s`` (its delay counts from there): raw bytes, or
        (in-process bus only) a message object the codec round-trips exactly."""
        if self._line is not None:
            self._line.push(self._params, payload, t_s)
        else:
            self._state = delay_line_push(self._state, self._params, payload, t_s)  # type: ignore[arg-type]

    def _pop_due(self, now_s: float) -> list[Delivered]:
        if self._line is not None:
            return self._line.pop_due(now_s)
        self._state, due = delay_line_pop_due(self._state, now_s)
        return due

    def release(self, now_s: float) -> list[Received]:
        """Decode and return everything due at ``now_s``."""
        if self._line is not None:
            due = self._line.pop_due_raw(now_s)
        else:
            due = _raw(self._pop_due(now_s))
        return self._deliver(due) if due else []

    def arrive_and_release(self, arrivals: Iterable[tuple[bytes, float]],
                           now_s: float) -> list[Received]:
        """:meth:`arrive` each ``(payload, t_s)`` then :meth:`release` at ``now_s``.

        Due messages are popped as they come so a large backlog does not pile up in the
        delay line (whose push is O(messages in flight)); the result is in release order.
        """
        due: list[Delivered] = []
        for payload, t_s in arrivals:
            self.arrive(payload, t_s)
            first = self.next_release_s()
            if first is not None and first <= now_s:
                due += self._pop_due(now_s)
        due += self._pop_due(now_s)
        due.sort(key=lambda d: d.release_t_s)
        return self._deliver(_raw(due))

    def _deliver(self, due: list[Due]) -> list[Received]:
        """``due``: ``(payload, sent_t_s, delivered_t_s, delay_s)`` of each released message."""
        out: list[Received] = []
        exact = self.spec.msg_type
        decoder, signal, seq_jumps = self._decoder, self.signal, self._seq_jumps
        cap = self.seq_jump_max
        for p, sent_t_s, delivered_t_s, delay_s in due:
            if type(p) is exact:  # an in-process message the codec round-trips exactly
                msg = p
                decoder.accept()
            else:
                msg = decoder.decode(p, exact)
                if msg is None:
                    continue
            seq = msg.header.seq
            last = self._last_seq
            if self._drop_stale and last is not None:
                if seq <= last:
                    decoder.reject("stale_seq", f"{signal} seq {seq} <= {last}")
                    continue
                # (without a cap, or within it, the check passes: asked only beyond it)
                if (cap is not None and seq - last > cap
                        and not self._check_seq_jump(msg, delivered_t_s)):
                    continue
            msg = self._check_energy(msg)
            if msg is None:
                continue
            self._last_seq = seq
            if seq_jumps:
                seq_jumps.clear()
            out.append(Received(signal, msg, sent_t_s, delivered_t_s, delay_s))
        self._delivered += len(out)
        return out

    def _check_seq_jump(self, msg: Message, t_s: float) -> bool:
        """False (rejected) if the message's ``seq`` runs too far ahead of the last accepted.

        A run of such rejections that looks like a live sender (see the module doc)
        re-synchronises the filter instead: True, with the last accepted ``seq`` moved to
        the run's previous message.  A rejected message whose energy total would fail the
        energy check as well is counted under that reason (``energy_jump`` or
        ``energy_decrease``: a forged total), otherwise as ``seq_jump``; either way nothing
        but this run moves.
        """
        seq = msg.header.seq
        cap = self.seq_jump_max
        last = self._last_seq
        if cap is None or last is None or seq - last <= cap:
            return True
        run = self._seq_jumps
        if run and not run[-1][0] < seq <= run[-1][0] + cap:
            run.clear()
        run.append((seq, t_s))
        if len(run) >= JUMP_REBASE_COUNT and t_s - run[0][1] >= SEQ_REBASE_MIN_S:
            self._last_seq = run[-2][0]
            run.clear()
            self.seq_rebases += 1
            return True
        total, last_j = msg.header.energy_total_j, self._epoch_energy_j
        if last_j is not None and total < last_j:
            self._decoder.reject("energy_decrease",
                                 f"{self.signal} total {total:.6g} J < {last_j:.6g} J")
        elif last_j is not None and total - last_j > self.energy_jump_max_j:
            self._decoder.reject("energy_jump", f"{self.signal} total jumps by "
                                 f"{total - last_j:.6g} J > {self.energy_jump_max_j:.6g} J")
        else:
            self._decoder.reject("seq_jump", f"{self.signal} seq {seq} > {last} + {cap}")
        return False

    def _check_energy(self, msg: Message) -> Message | None:
        """The message with its total continued across sender epochs, or None (rejected)."""
        total = msg.header.energy_total_j
        last = self._epoch_energy_j
        if last is None:  # first message of an epoch: continue from what was handed on
            fresh = msg.header.seq <= FIRST_SEQ and total <= self.energy_jump_max_j
            self._energy_offset_j = (self._presented_energy_j if fresh
                                     else self._presented_energy_j - total)
        elif total < last:
            self._decoder.reject("energy_decrease",
                                 f"{self.signal} total {total:.6g} J < {last:.6g} J")
            return None
        elif total - last > self.energy_jump_max_j:
            j = self._jumps
            seq = msg.header.seq
            plausible = self._last_seq is None or seq - self._last_seq <= REBASE_MAX_SEQ_GAP
            if not (j and seq > j[-1][0]
                    and 0.0 <= total - j[-1][1] <= self.energy_jump_max_j):
                j.clear()
            if plausible:
                j.append((seq, total))
            if len(j) < JUMP_REBASE_COUNT:
                self._decoder.reject("energy_jump", f"{self.signal} total jumps by "
                                     f"{total - last:.6g} J > {self.energy_jump_max_j:.6g} J")
                return None
            # a live sender back from an outage: new baseline, the jump is not credited
            self._energy_offset_j = self._presented_energy_j - total
            self.rebases += 1
        self._jumps.clear()
        self._epoch_energy_j = total
        self._presented_energy_j = shown = total + self._energy_offset_j
        if shown == total:
            return msg
        return replace(msg, header=replace(msg.header, energy_total_j=shown))  # type: ignore[type-var]

    def reset_seq(self) -> None:
        """The sender restarted: forget its sequence numbers and start a new energy epoch."""
        self._last_seq = None
        self._epoch_energy_j = None
        self._jumps.clear()
        self._seq_jumps.clear()
        self.epochs += 1

    def drop_in_flight(self) -> None:
        """Discard the messages in flight (from a sender that has been replaced)."""
        self.state = replace(self.state, pending=())

    def next_release_s(self) -> float | None:
        """When the next message is due, if any is in flight."""
        if self._line is not None:
            return self._line.next_release_s()
        return next_release_s(self._state)

    def stats(self) -> LinkStats:
        """This signal's counters."""
        s = self.state
        mean = s.delay_sum_s / s.n_delivered if s.n_delivered else float("nan")
        return LinkStats(self.signal, s.n_pushed, s.n_lost, s.n_duplicated, s.n_delivered,
                         self._delivered, mean, s.delay_max_s)


def _raw(due: list[Delivered]) -> list[Due]:
    """``due`` as the tuples :meth:`Inbox._deliver` reads."""
    return [(d.payload, d.sent_t_s, d.delivered_t_s, d.delay_s) for d in due]


def check_publish(role: str, signal: str, msg: Message) -> None:
    """Programming errors: a role publishing a signal it does not own, or a wrong type."""
    spec = signal_spec(signal)
    if spec.sender != role:
        raise ValueError(f"{role} cannot publish {signal!r} (sent by {spec.sender})")
    if type(msg) is not spec.msg_type:
        raise TypeError(f"{signal!r} carries {spec.msg_type.__name__}, "
                        f"got {type(msg).__name__}")


def make_inboxes(role: str, links: LinksConfig, decoder: SafeDecoder,
                 drop_stale: bool = True, energy_jump_max_j: float = math.inf,
                 seq_jump_max: int | None = None) -> dict[str, Inbox]:
    """One :class:`Inbox` per signal ``role`` receives."""
    check_role(role)
    return {name: Inbox(name, links, decoder, drop_stale, energy_jump_max_j, seq_jump_max)
            for name, spec in SIGNALS.items() if spec.receiver == role}


def check_receive(role: str, inboxes: dict[str, Inbox], signal: str) -> Inbox:
    """The inbox of ``signal``; ValueError if ``role`` does not receive it."""
    try:
        return inboxes[signal]
    except KeyError:
        spec = signal_spec(signal)
        raise ValueError(f"{role} does not receive {signal!r} "
                         f"(received by {spec.receiver})") from None
