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


def _ms(t: float, echo: float) -> MasterState:
    return MasterState(Header(1, t, 0.0), 0.0, 0.0, echo_t_s=echo)


def _hs(t: float, echo: float) -> HandState:
    f = FingerState(0.0, 0.0, 0.0, 0.0, (0.0,) * 9, (False,) * 9)
    return HandState(Header(1, t, 0.0), (f, f, f), 0.0, echo_t_s=echo)


def test_round_trip_measured_from_echoes_and_rate_limits(setup) -> None:  # type: ignore[no-untyped-def]
    """T = (t - master echo) + (t - hand echo); rises at once, falls at the decay rate; the
    gain drops at once and rises at gain_rise_per_s; no echo: the any-delay gain."""
    _, p = setup
    s = step_delay_adapt(DelayAdaptState(), p, None, None, 0.0, 1e-3)
    assert math.isinf(s.round_trip_s)
    assert s.gain == pytest.approx(target_gain(p, math.inf))
    s = step_delay_adapt(s, p, _ms(9.0, 9.5), _hs(9.0, 9.8), 10.0, 1e-3)  # no echo yet: -1
    assert s.round_trip_s == pytest.approx(0.7)
    s = step_delay_adapt(DelayAdaptState(round_trip_s=0.7, gain=1.0), p,
                         _ms(9.99, 9.99), _hs(9.99, 9.99), 10.0, 1e-3)
    assert s.round_trip_s == pytest.approx(0.7 - p.delay_decay_s_per_s * 1e-3)  # peak hold
    assert s.gain == pytest.approx(target_gain(p, s.round_trip_s))  # dropped at once
    g0 = s.gain
    for _ in range(10):
        s = step_delay_adapt(replace(s, round_trip_s=0.02), p, _ms(9.99, 9.99),
                             _hs(9.99, 9.99), 10.0, 1e-3)
    assert s.gain == pytest.approx(min(1.0, g0 + 10 * p.gain_rise_per_s * 1e-3))
    none = step_delay_adapt(DelayAdaptState(), p, _ms(0.0, -1.0), _hs(0.0, 0.0), 1.0, 1e-3)
    assert math.isinf(none.round_trip_s)


def test_only_two_layer_schedules() -> None:
    cfg = load_config().controller
    assert control_params(cfg).delay_adapt is not None
    assert control_params(replace(cfg, kind="direct")).delay_adapt is None
    assert control_params(replace(cfg, kind="tdpa")).delay_adapt is None
    off = replace(cfg, delay_adapt=replace(cfg.delay_adapt, enabled=False))
    assert control_params(off).delay_adapt is None
