"""Delay-aware transparency: the force-feedback gain scheduled on the measured round trip.

The passivity layer keeps ``two-layer`` passive for any delay, but passive is not stable: a
tank that holds energy pays for the same delay-induced limit cycle direct control shows.
Franken et al. (2011) let the transparency layer change without touching the passivity
layer; this module is such a change (gain scheduling on the measured delay, in the spirit of
the delay-dependent designs reviewed by Hokayem and Spong, Automatica 42(12), 2006).

Round trip, measured on the controller's clock only (no clock synchronisation): every
MasterState echoes the ``t_s`` of the latest ForceCommand the master had received and every
HandState that of the latest HandCommand, with ``echo_held_s``, how long the peer had held
that command when it sent the state (a duration on the peer's clock).  When a new message
arrives at controller time ``t_a``, ``a = t_a - echo_t_s - held`` is the pure transport
round trip of that leg (controller -> peer -> controller); the peer's hold ``held`` and the
controller's own hold of the leg's latest message add to the loop's delay (the hand's state
arrives every 25 ms).  The controller's hold counts as ``h``, the interval between arrivals
smoothed over ``INTERVAL_TAU_S`` (before a second message: the time since the first), not as
the sawtooth ``t - t_a``: with message loss the sawtooth's peaks (two, three lost states in
a row) made the estimate jump, the gain dropped at once and came back at its rise rate, and
that gain ripple alone held a ~1 Hz finger cycle at zero delay with 20 % loss (the sweep,
before this).  At controller time ``t``::

    T_meas = sum over legs (master, hand) of  a + min(held, c) + min(h, c)

A hold beyond ``c = stale_cap_s`` (~ the state watchdog's timeout) is an outage, not a
delay: no new information closes the loop, and the watchdogs ramp the force down; counting
it as delay would keep the gain low for a while after every outage.  The estimate is the
running maximum of ``T_meas`` over the last ``delay_window_s`` (two buckets of half a window,
``T = max(previous bucket, current bucket)``): it rises at once and falls back within the
window.  No echo yet: ``T = inf``.

Gain: with the linearised loop ``L(jw)`` of :mod:`teleop.control.stability_limit` for the
design plant (operator, servo, contact: ``controller.delay_adapt``), ``kappa_c(T)`` is the
largest factor on the force gain for which ``kappa L e^{-jwT}`` is stable:
``kappa_c(T) = inf {kappa : T_max(kappa L) <= T}``, falling from large values at ``T = 0``
to ``kappa_0 = 1 / max_w |L(jw)|`` as ``T -> inf`` (below ``kappa_0``, ``|kappa L| < 1`` at
every frequency: stable for any delay, passivity.md).  The target keeps the gain margin
``g``: ``kappa* = min(1, kappa_c(T) / g)``; the gain drops to ``kappa*`` at once (a drop of
at most ``DROP_DEADBAND`` of the gain is ignored) and rises towards it at most
``gain_rise_per_s``.  The displayed force asked of the passivity layer is
``kappa`` times the transparency layer's force (applied before the display filter).  At
small delays ``kappa_c / g >= 1``, so the zero-delay behaviour is unchanged.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace

import numpy as np

from teleop.config.control import ControllerConfig
from teleop.control.stability_limit import (
    DirectLoopParams,
    loop_gain,
    loop_params_from_config,
    predicted_max_stable_delay_s,
)
from teleop.frozen import fast_init
from teleop.messages import HandState, MasterState

#: The critical-gain table spans kappa_0 (+1e-5 of the range) .. KAPPA_TOP.
KAPPA_TOP = 20.0
_N_TABLE = 120


@dataclass(frozen=True, slots=True)
class DelayAdaptParams:
    """The schedule: ``kappa_c`` tabulated against round trip, and the rate limits."""

    delays_s: tuple[float, ...]  # increasing round trips
    kappas: tuple[float, ...]  # critical gain factor at each (decreasing)
    kappa_any_delay: float  # kappa_0 = 1 / max |L|: stable for any delay below it
    gain_margin: float
    gain_rise_per_s: float
    delay_window_s: float
    stale_cap_s: float


#: a target at most this fraction below the gain in use leaves the gain where it is (the
#: gain margin g = 2 keeps 1.8 of it); larger drops happen at once.  Without it every small
#: rise of the estimate stepped the force down and the rise rate brought it back: a ripple
#: the operator feels and the classifier counts
DROP_DEADBAND = 0.1

#: time constant of a leg's smoothed inter-arrival interval (s)
INTERVAL_TAU_S = 2.0


@fast_init
@dataclass(frozen=True, slots=True)
class LegState:
    """One leg's latest message (its ``t_s``), echo age at arrival, arrival time, and the
    smoothed interval between arrivals (nan until the second message)."""

    key_t_s: float = math.nan
    age_s: float = math.inf
    arrival_s: float = math.nan
    interval_s: float = math.nan


@fast_init
@dataclass(frozen=True, slots=True)
class DelayAdaptState:
    """Round-trip estimate (s; inf = unknown), its two max buckets, the gain in use (nan =
    not started)."""

    round_trip_s: float = math.inf
    gain: float = math.nan
    bucket_max_s: float = -math.inf  # max of T_meas in the current half-window
    prev_bucket_max_s: float = -math.inf  # ... in the previous one
    bucket_age_s: float = 0.0
    master_leg: LegState = field(default_factory=LegState)
    hand_leg: LegState = field(default_factory=LegState)


def design_loop(cfg: ControllerConfig) -> DirectLoopParams:
    """The linearised loop of the configured transparency layer on the design plant."""
    d = cfg.delay_adapt
    return loop_params_from_config(
        cfg, mass_kg=d.operator_mass_kg, damping_n_s_per_m=d.operator_damping_n_s_per_m,
        stiffness_n_per_m=d.operator_stiffness_n_per_m,
        contact_stiffness_nm_per_rad=d.contact_stiffness_nm_per_rad,
        pressure_per_nm=d.pressure_per_nm,
        servo_damping_nm_s_per_rad=d.servo_damping_nm_s_per_rad)


@functools.lru_cache(maxsize=32)
def critical_gain_table(loop: DirectLoopParams) -> tuple[tuple[float, ...], tuple[float, ...],
                                                         float]:
    """``(round trips, critical gains, kappa_0)`` of ``loop`` (cached: ~0.2 s to build)."""
    ws = np.logspace(-3, 5, 4000)
    peak = max(abs(loop_gain(loop, float(w))) for w in ws)
    k0 = 1.0 / peak if peak > 0 else math.inf
    if not math.isfinite(k0) or k0 >= KAPPA_TOP:
        return (0.0,), (KAPPA_TOP,), k0
    kap = k0 + (KAPPA_TOP - k0) * np.geomspace(1e-5, 1.0, _N_TABLE)  # dense near kappa_0
    t = [predicted_max_stable_delay_s(replace(loop, force_gain_n_per_nm=loop.force_gain_n_per_nm
                                              * float(k))) for k in kap]
    t_mono = np.minimum.accumulate(np.nan_to_num(np.array(t), posinf=1e9))  # decreasing in kappa
    order = np.argsort(t_mono, kind="stable")  # increasing delay, so decreasing kappa
    return (tuple(float(x) for x in t_mono[order]), tuple(float(x) for x in kap[order]), k0)


def delay_adapt_params(cfg: ControllerConfig) -> DelayAdaptParams | None:
    """The schedule for ``cfg`` (None when disabled)."""
    d = cfg.delay_adapt
    if not d.enabled:
        return None
    delays, kappas, k0 = critical_gain_table(design_loop(cfg))
    return DelayAdaptParams(delays_s=delays, kappas=kappas, kappa_any_delay=k0,
                            gain_margin=d.gain_margin, gain_rise_per_s=d.gain_rise_per_s,
                            delay_window_s=d.delay_window_s, stale_cap_s=d.stale_cap_s)


def critical_gain(p: DelayAdaptParams, round_trip_s: float) -> float:
    """``kappa_c(T)``: the largest stable gain factor at round trip ``T`` (model)."""
    if not math.isfinite(round_trip_s):
        return p.kappa_any_delay
    if round_trip_s >= p.delays_s[-1]:
        return p.kappa_any_delay
    memo = _last_gain
    if memo[0] is p and memo[1] == round_trip_s and memo[2] == math.copysign(1.0, round_trip_s):
        return memo[3]  # the round trip rarely moves: the same input, the same number
    k = float(np.interp(round_trip_s, p.delays_s, p.kappas))
    _set_last_gain((p, round_trip_s, math.copysign(1.0, round_trip_s), k))
    return k


#: (params, round trip, its sign, kappa) of the last :func:`critical_gain` interpolation (one
#: tuple, replaced whole, so a reader in another thread sees a consistent entry)
_last_gain: tuple[DelayAdaptParams | None, float, float, float] = (None, math.nan, 0.0, 0.0)


def _set_last_gain(entry: tuple[DelayAdaptParams | None, float, float, float]) -> None:
    global _last_gain
    _last_gain = entry


def target_gain(p: DelayAdaptParams, round_trip_s: float) -> float:
    """``min(1, kappa_c(T) / g)``."""
    return min(1.0, critical_gain(p, round_trip_s) / p.gain_margin)


#: an echo this far "from the future" is tick jitter, not an implausible echo: the live
#: services stamp messages with their nominal tick times while the peers measure their holds
#: on real time, so a late controller tick sees transports a few ms below zero
ECHO_JITTER_S = 0.05


def echo_age_s(msg: MasterState | HandState | None, t_s: float, stale_cap_s: float) -> float:
    """Round trip of the echoed command at ``t_s``: ``t - echo_t_s`` with the peer's hold
    capped at ``stale_cap_s`` (inf when nothing is echoed yet, or when the echo is
    implausible: more than ``ECHO_JITTER_S`` from the future, e.g. a timestamp of a previous
    controller process; a transport just below zero counts as zero)."""
    if msg is None or not math.isfinite(msg.echo_t_s) or msg.echo_t_s < 0.0:
        return math.inf
    held = msg.echo_held_s if math.isfinite(msg.echo_held_s) else 0.0
    held = max(held, 0.0)
    transport = t_s - msg.echo_t_s - held
    if transport < -ECHO_JITTER_S:
        return math.inf
    return max(transport, 0.0) + min(held, stale_cap_s)


def step_leg(leg: LegState, msg: MasterState | HandState | None, t_s: float,
             stale_cap_s: float) -> tuple[LegState, float]:
    """Register a new message (a new ``t_s``); return the leg's round trip ``a + min(held, c)
    + min(h, c)`` (inf before the first echo), ``h`` the controller's own hold: the smoothed
    interval between arrivals (the time since the last arrival until a second one came)."""
    if msg is not None and msg.header.t_s != leg.key_t_s:
        interval = leg.interval_s
        if math.isfinite(leg.arrival_s):
            gap = min(max(t_s - leg.arrival_s, 0.0), stale_cap_s)
            k = min(1.0, gap / INTERVAL_TAU_S)
            interval = gap if not math.isfinite(interval) else interval + k * (gap - interval)
        leg = LegState(key_t_s=msg.header.t_s, age_s=echo_age_s(msg, t_s, stale_cap_s),
                       arrival_s=t_s, interval_s=interval)
    if not math.isfinite(leg.age_s):
        return leg, math.inf
    hold = (leg.interval_s if math.isfinite(leg.interval_s)
            else max(t_s - leg.arrival_s, 0.0))
    return leg, leg.age_s + min(hold, stale_cap_s)


def step_delay_adapt(s: DelayAdaptState, p: DelayAdaptParams | None, master: MasterState | None,
                     hand: HandState | None, t_s: float, dt_s: float) -> DelayAdaptState:
    """Update the round-trip estimate and the gain (see module docstring)."""
    if p is None:
        return DelayAdaptState(round_trip_s=s.round_trip_s, gain=1.0)
    dt = max(dt_s, 0.0)
    m_leg, a_m = step_leg(s.master_leg, master, t_s, p.stale_cap_s)
    h_leg, a_h = step_leg(s.hand_leg, hand, t_s, p.stale_cap_s)
    meas = a_m + a_h
    age = s.bucket_age_s + dt
    cur, prev_b = max(s.bucket_max_s, meas), s.prev_bucket_max_s
    if age >= 0.5 * p.delay_window_s:  # start a new half-window
        cur, prev_b, age = meas, cur, 0.0
    rt = max(cur, prev_b)
    want = target_gain(p, rt)
    prev = s.gain if math.isfinite(s.gain) else target_gain(p, math.inf)
    if prev * (1.0 - DROP_DEADBAND) <= want < prev:
        want = prev  # a small drop is ignored: it stays inside the gain margin
    gain = min(want, prev + p.gain_rise_per_s * dt)
    return DelayAdaptState(round_trip_s=rt, gain=max(gain, 0.0), bucket_max_s=cur,
                           prev_bucket_max_s=prev_b, bucket_age_s=age, master_leg=m_leg,
                           hand_leg=h_leg)
