"""The delay-aware force gain of ``two-layer`` (teleop/control/delay_adapt.py)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from teleop.config import load_config
from teleop.control.delay_adapt import (
    DelayAdaptState,
    critical_gain,
    delay_adapt_params,
    design_loop,
    step_delay_adapt,
    target_gain,
)
from teleop.control.interface import control_params
from teleop.control.stability_limit import loop_gain, predicted_max_stable_delay_s
from teleop.messages import FingerState, HandState, Header, MasterState


@pytest.fixture(scope="module")
def setup():  # type: ignore[no-untyped-def]
    cfg = load_config().controller
    p = delay_adapt_params(cfg)
    assert p is not None
    return cfg, p


def _scaled(loop, k: float):  # type: ignore[no-untyped-def]
    return replace(loop, force_gain_n_per_nm=loop.force_gain_n_per_nm * k)


@pytest.mark.parametrize("round_trip_s", [0.03, 0.05, 0.08, 0.13, 0.25, 0.5, 1.0, 2.0, 5.0])
def test_scheduled_loop_keeps_its_gain_margin(setup, round_trip_s: float) -> None:  # type: ignore[no-untyped-def]
    """With kappa(T) the design loop is stable at T, and stays stable with g x kappa(T) at
    (almost) T: the margin is a gain margin at the measured delay."""
    cfg, p = setup
    loop = design_loop(cfg)
    k = target_gain(p, round_trip_s)
    assert predicted_max_stable_delay_s(_scaled(loop, k)) > round_trip_s
    kc = critical_gain(p, round_trip_s)
    assert predicted_max_stable_delay_s(_scaled(loop, 0.97 * kc)) >= 0.97 * round_trip_s
    assert predicted_max_stable_delay_s(_scaled(loop, 1.03 * kc)) <= 1.03 * round_trip_s


def test_zero_delay_unchanged_and_any_delay_bounded(setup) -> None:  # type: ignore[no-untyped-def]
    """Full gain at the loop's intrinsic ~27 ms round trip; for an unknown or huge delay the
    gain keeps |kappa L(jw)| <= 1/g at every frequency (stable for any delay)."""
    cfg, p = setup
    assert target_gain(p, 0.0) == 1.0
    assert target_gain(p, 0.027) == 1.0
    loop = design_loop(cfg)
    peak = max(abs(loop_gain(loop, float(w))) for w in np.logspace(-3, 5, 4000))
    for t in (math.inf, 1e3):
        k = target_gain(p, t)
        assert k * peak <= 1.0 / p.gain_margin + 1e-9
    gains = [target_gain(p, t) for t in np.linspace(0.0, 3.0, 301)]
    assert all(a >= b - 1e-12 for a, b in zip(gains, gains[1:], strict=False))  # monotone


def _ms(t: float, echo: float, held: float = 0.0) -> MasterState:
    return MasterState(Header(1, t, 0.0), 0.0, 0.0, echo_t_s=echo, echo_held_s=held)


def _hs(t: float, echo: float, held: float = 0.0) -> HandState:
    f = FingerState(0.0, 0.0, 0.0, 0.0, (0.0,) * 9, (False,) * 9)
    return HandState(Header(1, t, 0.0), (f, f, f), 0.0, echo_t_s=echo, echo_held_s=held)


def test_round_trip_measured_from_echoes(setup) -> None:  # type: ignore[no-untyped-def]
    """T = sum over legs of (t_a - echo - held) + min(held, c) + min(h, c), ``h`` the time
    since the first arrival until a second one came, then the smoothed interval."""
    _, p = setup
    c = p.stale_cap_s
    s = step_delay_adapt(DelayAdaptState(), p, None, None, 0.0, 1e-3)
    assert math.isinf(s.round_trip_s)  # nothing echoed yet: unknown
    assert s.gain == pytest.approx(target_gain(p, math.inf))
    s = step_delay_adapt(DelayAdaptState(), p, _ms(9.9, -1.0), _hs(9.9, 9.8), 10.0, 1e-3)
    assert math.isinf(s.round_trip_s)
    s = step_delay_adapt(DelayAdaptState(), p, _ms(9.9, 9.5), _hs(9.9, 9.78, 0.02), 10.0, 1e-3)
    assert s.round_trip_s == pytest.approx(0.5 + 0.22)
    s = step_delay_adapt(DelayAdaptState(), p, _ms(9.9, 9.5), _hs(9.9, 8.8, 1.0), 10.0, 1e-3)
    assert s.round_trip_s == pytest.approx(0.5 + 0.2 + c)  # a long hold is an outage
    # the controller's own hold adds until the next message, capped likewise
    m, h = _ms(9.9, 9.5), _hs(9.9, 9.8)
    s = step_delay_adapt(DelayAdaptState(), p, m, h, 10.0, 1e-3)
    s2 = step_delay_adapt(s, p, m, h, 10.03, 0.03)
    assert s2.round_trip_s == pytest.approx(0.7 + 2 * 0.03)
    s3 = step_delay_adapt(s2, p, m, h, 12.0, 1.97)
    assert s3.round_trip_s == pytest.approx(0.7 + 2 * c)
    future = step_delay_adapt(DelayAdaptState(), p, _ms(9.9, 10.5), h, 10.0, 1e-3)
    assert math.isinf(future.round_trip_s)  # an echo from the future is not trusted


def test_estimate_window_and_gain_rate_limits(setup) -> None:  # type: ignore[no-untyped-def]
    """The estimate rises at once and falls back within the window; the gain drops at once
    and rises at gain_rise_per_s."""
    _, p = setup
    dt = 1e-3
    s = DelayAdaptState(gain=1.0)
    t = 10.0
    s = step_delay_adapt(s, p, _ms(t, t - 0.6), _hs(t, t - 0.1), t, dt)  # 0.7 s
    assert s.round_trip_s == pytest.approx(0.7)
    assert s.gain == pytest.approx(target_gain(p, 0.7))  # dropped at once
    g0 = s.gain
    n = int(round(1.2 * p.delay_window_s / dt)) + 2
    gains = []
    for k in range(1, n):
        t = 10.0 + k * dt
        s = step_delay_adapt(s, p, _ms(t, t - 0.002), _hs(t, t - 0.002), t, dt)
        gains.append(s.gain)
    # the window has passed: 2 ms per leg plus each leg's 1 ms interval between messages
    assert s.round_trip_s == pytest.approx(0.006)
    rises = np.diff([g0, *gains])
    assert np.all(rises <= p.gain_rise_per_s * dt + 1e-12)
    assert gains[-1] > g0
    for _ in range(int(1.0 / p.gain_rise_per_s / dt) + 1):  # full gain after 1 / rate
        t += dt
        s = step_delay_adapt(s, p, _ms(t, t - 0.002), _hs(t, t - 0.002), t, dt)
    assert s.gain == 1.0


def test_only_two_layer_schedules() -> None:
    cfg = load_config().controller
    assert control_params(cfg).delay_adapt is not None
    assert control_params(replace(cfg, kind="direct")).delay_adapt is None
    assert control_params(replace(cfg, kind="tdpa")).delay_adapt is None
    off = replace(cfg, delay_adapt=replace(cfg.delay_adapt, enabled=False))
    assert control_params(off).delay_adapt is None


def test_an_echo_a_few_ms_from_the_future_is_tick_jitter_not_an_outage() -> None:
    """Live, the services stamp messages with their nominal tick times while the peers
    measure their holds on real time: a late controller tick sees a transport a few ms below
    zero.  That must read as no delay; it read as an unknown round trip and dropped the force
    gain to its any-delay floor several times a second (the live ~1-2 Hz cycle of issue 13)."""
    from teleop.control.delay_adapt import ECHO_JITTER_S, echo_age_s

    jitter = _hs(10.0, 9.99, 0.015)  # echoed 10 ms ago, held 15 ms: 5 ms "from the future"
    assert echo_age_s(jitter, 10.0, 0.1) == pytest.approx(0.015)
    stale = _hs(10.0, 10.0 + 2 * ECHO_JITTER_S, 0.0)  # a previous process's timestamp
    assert echo_age_s(stale, 10.0, 0.1) == math.inf


def test_lost_states_raise_the_estimate_smoothly_not_in_jumps(setup) -> None:  # type: ignore[no-untyped-def]
    """20 % of the hand's 40 Hz states lost: the estimate follows the mean interval (one
    state period plus a little), it does not jump to the longest gap; no gain ripple."""
    _, p = setup
    rng = np.random.default_rng(4)
    s = DelayAdaptState(gain=1.0)
    dt = 1e-3
    hand = None
    rts, gains = [], []
    for k in range(8000):
        t = k * dt
        if k % 25 == 0 and (hand is None or rng.random() > 0.2):
            hand = _hs(t, t - 0.002)
        s = step_delay_adapt(s, p, _ms(t, t - 0.002), hand, t, dt)
        if t > 4.0:
            rts.append(s.round_trip_s)
            gains.append(s.gain)
    assert max(rts) < 0.002 + 0.002 + 0.001 + 0.045  # ~1.25 periods smoothed, never 3
    assert max(gains) - min(gains) < 0.05
