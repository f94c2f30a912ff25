"""A mutable delay line for an :class:`~teleop.transport.bus.Inbox` on a link without jitter or
duplicates: the same releases, counters and achieved delays as the pure
:func:`~teleop.transport.delay_line.delay_line_push` / ``delay_line_pop_due`` (the
reference), without rebuilding a frozen state and re-copying every message in flight per
message (a 1 s delay at 1 kHz holds a thousand).

It makes the operations of the pure paths in their order: the loss draw
(:func:`~teleop.transport.delay_line.lost_draw`), the one copy's release
(:func:`~teleop.transport.delay_line.plain_release`), the in-order append (a sorted
insertion otherwise), and on release the delay sum of the pure pops (one due message:
``+ (0 + d)``; several: ``+ sum(delays)``) and their ``max``.  :meth:`FastLine.state` gives
the pure state back (and :meth:`FastLine.of` takes one), so the pure functions can continue
from either side.
``tests/teleop/transport/test_fast_line.py`` holds the two to each other.
"""

from __future__ import annotations

import bisect
from collections import deque

from teleop.transport.delay_line import (
    TIME_EPS_S,
    DelayLineState,
    DelayParams,
    Delivered,
    Pending,
    lost_draw,
    plain_release,
)

__all__ = ["Due", "FastLine", "fast_params"]


def fast_params(p: DelayParams) -> bool:
    """Whether :class:`FastLine` serves links with ``p`` (no jitter, no duplicates)."""
    return (p.jitter == "none" or p.jitter_s <= 0.0) and p.duplicate <= 0.0


#: an entry in flight, as a plain tuple (no frozen object per message): the fields of
#: :class:`~teleop.transport.delay_line.Pending` in their order
Entry = tuple[float, int, float, object, bool]
#: a released message: ``(payload, sent_t_s, delivered_t_s, delay_s)`` (what
#: :meth:`~teleop.transport.bus.Inbox.release` reads of a ``Delivered``)
Due = tuple[object, float, float, float]


def _key(e: Entry) -> tuple[float, int]:
    return (e[0], e[1])


def _release_t(e: Entry) -> float:
    return e[0]


class FastLine:
    """Messages in flight on one link direction and its counters (see the module doc)."""

    __slots__ = ("pending", "n_pushed", "n_lost", "n_duplicated", "n_delivered", "bad",
                 "last_release_t_s", "delay_sum_s", "delay_max_s")

    def __init__(self, s: DelayLineState) -> None:
        self.pending: deque[Entry] = deque(
            (e.release_t_s, e.order, e.sent_t_s, e.payload, e.duplicate) for e in s.pending)
        self.n_pushed, self.n_lost, self.n_duplicated = s.n_pushed, s.n_lost, s.n_duplicated
        self.n_delivered, self.bad = s.n_delivered, s.bad
        self.last_release_t_s = s.last_release_t_s
        self.delay_sum_s, self.delay_max_s = s.delay_sum_s, s.delay_max_s

    @classmethod
    def of(cls, state: DelayLineState) -> FastLine:
        """A line continuing from the pure ``state``."""
        return cls(state)

    def state(self) -> DelayLineState:
        """The pure state of this line now."""
        return DelayLineState(tuple(Pending(*e) for e in self.pending),  # type: ignore[arg-type]
                              self.n_pushed, self.n_lost,
                              self.n_duplicated, self.n_delivered, self.bad,
                              self.last_release_t_s, self.delay_sum_s, self.delay_max_s)

    def push(self, params: DelayParams, payload: object, t_s: float) -> None:
        """:func:`~teleop.transport.delay_line.delay_line_push` (``fast_params(params)``)."""
        i = self.n_pushed
        self.n_pushed = i + 1
        if params.loss > 0.0:
            lost, self.bad = lost_draw(self.bad, params, i)
            if lost:
                self.n_lost += 1
                return
        release, self.last_release_t_s = plain_release(params, t_s, self.last_release_t_s)
        entry = (release, 2 * i, t_s, payload, False)
        pending = self.pending
        if not pending:
            pending.append(entry)
            return
        last = pending[-1]
        lt = last[0]
        # ``_key(last) <= _key(entry)`` for the usual case (two comparisons, no tuples);
        # anything else (equal or unordered times) asks the tuples themselves
        if lt < release or _key(last) <= _key(entry):
            pending.append(entry)
        else:
            ordered = list(pending)
            bisect.insort(ordered, entry, key=_key)
            self.pending = deque(ordered)

    def pop_due(self, t_s: float) -> list[Delivered]:
        """:func:`~teleop.transport.delay_line.delay_line_pop_due`: everything due at ``t_s``
        (:meth:`pop_due_raw` as ``Delivered`` objects)."""
        n = bisect.bisect_right(self.pending, t_s + TIME_EPS_S, key=_release_t)
        got = [self.pending[j] for j in range(n)]
        return [Delivered(e[3], e[2], e[0], t_s, r[3], e[4])  # type: ignore[arg-type]
                for e, r in zip(got, self.pop_due_raw(t_s), strict=True)]

    def pop_due_raw(self, t_s: float) -> list[Due]:
        """:meth:`pop_due` as ``(payload, sent_t_s, delivered_t_s, delay_s)`` tuples (the same
        releases, counters and delays; no ``Delivered`` objects)."""
        pending = self.pending
        due_t = t_s + TIME_EPS_S
        if not pending or pending[0][0] > due_t:
            return []
        if len(pending) == 1 or pending[1][0] > due_t:
            e = pending.popleft()
            sent = e[2]
            d = t_s - sent
            self.n_delivered += 1
            self.delay_sum_s = self.delay_sum_s + (0 + d)  # sum([d]) exactly
            self.delay_max_s = max(self.delay_max_s, d)
            return [(e[3], sent, t_s, d)]
        n = bisect.bisect_right(pending, due_t, key=_release_t)
        popleft = pending.popleft
        out = []
        for _ in range(n):
            e = popleft()
            out.append((e[3], e[2], t_s, t_s - e[2]))
        delays = [d[3] for d in out]
        self.n_delivered += n
        self.delay_sum_s = self.delay_sum_s + sum(delays)
        self.delay_max_s = max(self.delay_max_s, *delays)
        return out

    def next_release_s(self) -> float | None:
        """When the next message is due (None when nothing is in flight)."""
        return self.pending[0][0] if self.pending else None
