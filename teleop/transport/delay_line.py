"""A pure, seeded delay line: one per link and direction.

It models a one-way network path between a sender and a receiver:

* delay: the constant one-way ``delay_s`` plus a non-negative jitter, so a message is never
  delivered before ``delay_s`` has passed (``none``; ``uniform`` in [0, jitter_s];
  ``normal``: half-normal |N(0, jitter_s)|; ``pareto``: heavy-tailed Lomax with scale
  ``jitter_s`` and shape :data:`PARETO_SHAPE`, mean ``jitter_s / (shape - 1)``);
* loss: ``bernoulli`` (independent, probability ``loss``) or ``gilbert`` (a two-state
  Gilbert-Elliott chain that loses every message in the bad state; mean loss rate ``loss``,
  mean burst length ``burst_length``; stationary start; bad->good probability
  ``1/burst_length``, good->bad ``loss/(burst_length (1-loss))``, which must be <= 1: a
  rate above ``burst_length/(burst_length+1)`` is clamped there);
* duplication: with probability ``duplicate`` a second copy with its own delay;
* reordering: on, messages are released in order of their sampled release times; off,
  release times are made non-decreasing (FIFO: nothing overtakes an earlier message).

Randomness is counter based (a splitmix64 hash of the seed, the message index and the draw),
so the outcome depends only on the seed and the sequence of pushes, not on timing, and the
state needs no random generator: :func:`delay_line_push` and :func:`delay_line_pop_due` are
pure functions of (state, params, input).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

from teleop.config.transport import LinkConfig
from teleop.frozen import fast_init

PARETO_SHAPE = 2.5
MAX_DELAY_S = 60.0  # cap on one sampled delay (the heavy tail is unbounded)
#: Release times within this of the pop time count as due (absorbs float rounding of t + d
#: on a fixed-step virtual clock, e.g. 0.001 * i + 0.05).
TIME_EPS_S = 1e-9
_M64 = (1 << 64) - 1


def _mix(x: int) -> int:
    """splitmix64 finaliser."""
    x = (x + 0x9E3779B97F4A7C15) & _M64
    x = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & _M64
    x = ((x ^ (x >> 27)) * 0x94D049BB133111EB) & _M64
    return x ^ (x >> 31)


def _uniform(stream: int, index: int, draw: int) -> float:
    """A uniform number in (0, 1) for (stream, message index, draw number)."""
    x = _mix(stream ^ _mix(index * 16 + draw))
    return ((x >> 11) + 0.5) / 9007199254740992.0


@dataclass(frozen=True, slots=True)
class DelayParams:
    """Impairments of one direction of one link (see :func:`delay_params`)."""

    delay_s: float = 0.0
    jitter: str = "none"
    jitter_s: float = 0.0
    loss: float = 0.0
    loss_model: str = "bernoulli"
    burst_length: float = 5.0
    duplicate: float = 0.0
    reorder: bool = True
    stream: int = 0  # seed of the random stream (derived from the link seed and direction)


def delay_params(link: LinkConfig, forward: bool, salt: int = 0) -> DelayParams:
    """Params of one direction of ``link``; ``salt`` separates links sharing a seed."""
    delay = link.delay_s if forward or link.backward_delay_s is None else link.backward_delay_s
    stream = _mix(_mix(link.seed) ^ (salt * 2 + (0 if forward else 1)))
    return DelayParams(delay, link.jitter, link.jitter_s, link.loss, link.loss_model,
                       link.burst_length, link.duplicate, link.reorder, stream)


@fast_init
@dataclass(frozen=True, slots=True)
class Pending:
    """A message in flight."""

    release_t_s: float
    order: int
    sent_t_s: float
    payload: bytes  # or, on the in-process bus, an immutable message object
    duplicate: bool


@fast_init
@dataclass(frozen=True, slots=True)
class Delivered:
    """A message released by the delay line."""

    payload: bytes
    sent_t_s: float
    release_t_s: float  # scheduled release
    delivered_t_s: float  # when it was popped (>= release_t_s - TIME_EPS_S)
    delay_s: float  # achieved delay: delivered_t_s - sent_t_s
    duplicate: bool


@dataclass(frozen=True, slots=True)
class DelayLineState:
    """Everything in flight plus counters; start with ``DelayLineState()``."""

    pending: tuple[Pending, ...] = ()  # sorted by (release_t_s, order)
    n_pushed: int = 0
    n_lost: int = 0
    n_duplicated: int = 0
    n_delivered: int = 0
    bad: bool | None = None  # Gilbert chain state (None before the first message)
    last_release_t_s: float = -math.inf
    delay_sum_s: float = 0.0  # of achieved delays of delivered messages
    delay_max_s: float = 0.0


def _lost(state: DelayLineState, p: DelayParams, i: int) -> tuple[bool, bool | None]:
    """(lost?, new Gilbert state) for message ``i``."""
    return lost_draw(state.bad, p, i)


def lost_draw(bad_before: bool | None, p: DelayParams, i: int) -> tuple[bool, bool | None]:
    """(lost?, new Gilbert state) for message ``i`` with the chain in ``bad_before``."""
    if p.loss <= 0.0:
        return False, bad_before
    u = _uniform(p.stream, i, 0)
    if p.loss_model == "bernoulli":
        return u < p.loss, bad_before
    if p.loss >= 1.0:
        return True, True
    if bad_before is None:  # start in the stationary distribution
        bad = u < p.loss
    else:
        r = 1.0 / p.burst_length  # bad -> good
        g2b = min(1.0, p.loss * r / (1.0 - p.loss))  # good -> bad, so P(bad) = loss
        bad = (u >= r) if bad_before else (u < g2b)
    return bad, bad


def _no_jitter(p: DelayParams) -> bool:
    return p.jitter == "none" or p.jitter_s <= 0.0


def _jitter(p: DelayParams, i: int, draw: int) -> float:
    if _no_jitter(p):
        return 0.0
    u = _uniform(p.stream, i, draw)
    if p.jitter == "uniform":
        return p.jitter_s * u
    if p.jitter == "normal":
        u2 = _uniform(p.stream, i, draw + 1)
        return abs(p.jitter_s * math.sqrt(-2.0 * math.log(u)) * math.cos(2.0 * math.pi * u2))
    if p.jitter == "pareto":
        return p.jitter_s * (u ** (-1.0 / PARETO_SHAPE) - 1.0)
    raise ValueError(f"unknown jitter distribution {p.jitter!r}")


def _sample_delay(p: DelayParams, i: int, draw: int) -> float:
    return min(p.delay_s + _jitter(p, i, draw), MAX_DELAY_S)


def _key(e: Pending) -> tuple[float, int]:
    return (e.release_t_s, e.order)


def _insert(pending: tuple[Pending, ...], entry: Pending) -> tuple[Pending, ...]:
    """``pending`` with ``entry`` in release order (appended in the common in-order case)."""
    if not pending or _key(pending[-1]) <= _key(entry):
        return (*pending, entry)
    ordered = list(pending)
    bisect.insort(ordered, entry, key=_key)
    return tuple(ordered)


def delay_line_push(state: DelayLineState, params: DelayParams, payload: bytes,
                    t_s: float) -> DelayLineState:
    """Send ``payload`` at ``t_s``: schedule its release (or lose it, or duplicate it)."""
    i = state.n_pushed
    if params.loss <= 0.0 and params.duplicate <= 0.0 and _no_jitter(params):
        return _push_plain(state, params, payload, t_s, i)
    return _push_general(state, params, payload, t_s, i)


def _push_general(state: DelayLineState, params: DelayParams, payload: bytes, t_s: float,
                  i: int) -> DelayLineState:
    """:func:`delay_line_push` with any impairment (loss, duplicates, jitter)."""
    lost, bad = _lost(state, params, i)
    if lost:
        return DelayLineState(state.pending, i + 1, state.n_lost + 1, state.n_duplicated,
                              state.n_delivered, bad, state.last_release_t_s,
                              state.delay_sum_s, state.delay_max_s)
    copies = [(_sample_delay(params, i, 2), False)]
    if params.duplicate > 0.0 and _uniform(params.stream, i, 1) < params.duplicate:
        copies.append((_sample_delay(params, i, 4), True))
    pending = state.pending
    last = state.last_release_t_s
    for k, (d, dup) in enumerate(copies):
        release = t_s + d
        if not params.reorder:
            release = max(release, last)
        last = max(last, release)
        pending = _insert(pending, Pending(release, 2 * i + k, t_s, payload, dup))
    return DelayLineState(pending, i + 1, state.n_lost, state.n_duplicated + len(copies) - 1,
                          state.n_delivered, bad, last, state.delay_sum_s, state.delay_max_s)


def plain_release(params: DelayParams, t_s: float, last: float) -> tuple[float, float]:
    """(release time, new last release) of the one copy of a message sent at ``t_s`` on a
    link without jitter: ``_sample_delay`` and the FIFO ``max`` of :func:`_push_general`
    written as the comparisons they make."""
    d = params.delay_s + 0.0  # _sample_delay with no jitter
    if d > MAX_DELAY_S:
        d = MAX_DELAY_S
    release = t_s + d
    if not params.reorder and last > release:
        release = last
    if release > last:
        last = release
    return release, last


def _push_plain(state: DelayLineState, params: DelayParams, payload: bytes, t_s: float,
                i: int) -> DelayLineState:
    """:func:`delay_line_push` without loss, duplicates or jitter: the same operations on the
    one copy (``min``/``max`` written as the comparisons they make), none of the draws."""
    release, last = plain_release(params, t_s, state.last_release_t_s)
    pending = _insert(state.pending, Pending(release, 2 * i, t_s, payload, False))
    return DelayLineState(pending, i + 1, state.n_lost, state.n_duplicated, state.n_delivered,
                          state.bad, last, state.delay_sum_s, state.delay_max_s)


def _release_t(e: Pending) -> float:
    return e.release_t_s


def delay_line_pop_due(state: DelayLineState,
                       t_s: float) -> tuple[DelayLineState, list[Delivered]]:
    """Release every message due at ``t_s`` (in release order) with its achieved delay."""
    pending = state.pending
    if not pending or pending[0].release_t_s > t_s + TIME_EPS_S:
        return state, []
    if len(pending) == 1 or pending[1].release_t_s > t_s + TIME_EPS_S:
        return _pop_one(state, t_s)
    return _pop_general(state, t_s)


def _pop_one(state: DelayLineState, t_s: float) -> tuple[DelayLineState, list[Delivered]]:
    """:func:`_pop_general` when only the first message is due, without its lists."""
    e = state.pending[0]
    d = t_s - e.sent_t_s
    return DelayLineState(state.pending[1:], state.n_pushed, state.n_lost, state.n_duplicated,
                          state.n_delivered + 1, state.bad, state.last_release_t_s,
                          state.delay_sum_s + (0 + d),  # sum([d]) exactly
                          max(state.delay_max_s, d)), [
        Delivered(e.payload, e.sent_t_s, e.release_t_s, t_s, d, e.duplicate)]


def _pop_general(state: DelayLineState,
                 t_s: float) -> tuple[DelayLineState, list[Delivered]]:
    """Release everything due at ``t_s`` (at least the first message is)."""
    pending = state.pending
    n = bisect.bisect_right(pending, t_s + TIME_EPS_S, key=_release_t)
    out = [Delivered(e.payload, e.sent_t_s, e.release_t_s, t_s, t_s - e.sent_t_s, e.duplicate)
           for e in pending[:n]]
    delays = [d.delay_s for d in out]
    return DelayLineState(pending[n:], state.n_pushed, state.n_lost, state.n_duplicated,
                          state.n_delivered + n, state.bad, state.last_release_t_s,
                          state.delay_sum_s + sum(delays),
                          max(state.delay_max_s, *delays)), out


def next_release_s(state: DelayLineState) -> float | None:
    """When the next message is due (None when nothing is in flight)."""
    return state.pending[0].release_t_s if state.pending else None
