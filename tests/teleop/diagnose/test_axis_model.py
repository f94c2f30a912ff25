"""Physics of the axis simulator used by ``teleop diagnose`` and its synthetic recordings."""

from __future__ import annotations

import math

import numpy as np

from teleop.diagnose.axis_model import AxisParams, play, simulate_axis
from teleop.diagnose.residual import autocorr, noise_std
from teleop.effects import EffectSet


def test_free_linear_response_matches_the_analytic_damped_oscillator() -> None:
    J, b, k = 1.5, 0.6, 90.0
    t = np.arange(0, 3, 0.004)
    x = simulate_axis(t, None, AxisParams(J, b, k), x0=1.0, max_dt_s=0.004)
    wn = math.sqrt(k / J)
    z = b / (2 * math.sqrt(k * J))
    wd = wn * math.sqrt(1 - z * z)
    exact = np.exp(-z * wn * t) * (np.cos(wd * t) + z * wn / wd * np.sin(wd * t))
    assert np.max(np.abs(x - exact)) < 1e-9


def test_static_deflection_under_a_constant_effort_is_f_over_k() -> None:
    t = np.arange(0, 20, 0.002)
    x = simulate_axis(t, np.full(len(t), 3.0), AxisParams(1.0, 4.0, 60.0))
    assert abs(x[-1] - 3.0 / 60.0) < 1e-6


def test_coulomb_friction_makes_the_amplitude_fall_by_4c_over_k_per_cycle() -> None:
    J, k, c = 1.0, 100.0, 2.0
    t = np.arange(0, 10.0, 0.0002)
    x = simulate_axis(t, None, AxisParams(J, 0.0, k), EffectSet(coulomb_friction=c), x0=1.0,
                      max_dt_s=0.0002)
    period = 2 * math.pi / math.sqrt(k / J)
    i = int(round(period / 0.0002))
    assert abs((x[0] - x[i]) - 4 * c / k) < 0.003
    # and it stops inside the band |x| <= c/k, for good
    assert abs(x[-1]) <= c / k + 1e-9
    assert np.ptp(x[-500:]) < 1e-9


def test_stiction_holds_the_axis_until_the_effort_exceeds_breakaway() -> None:
    t = np.arange(0, 2, 0.001)
    u = np.where(t < 1.0, 2.9, 3.1)  # breakaway at fc + fs = 3
    x = simulate_axis(t, u, AxisParams(1.0, 1.0, 0.0), EffectSet(coulomb_friction=1.0,
                                                                stiction=2.0))
    assert np.ptp(x[t < 1.0]) == 0.0
    assert x[-1] > 1e-3


def test_dead_time_delays_the_response_by_the_dead_time() -> None:
    t = np.arange(0, 3, 0.001)
    u = np.where(t > 0.5, 10.0, 0.0)
    p = AxisParams(1.0, 5.0, 50.0)
    x0 = simulate_axis(t, u, p)
    x1 = simulate_axis(t, u, p, EffectSet(dead_time=0.1))
    assert np.allclose(x1[100:], x0[:-100], atol=1e-9)


def test_saturation_gain_and_offset_act_as_named() -> None:
    t = np.arange(0, 20, 0.002)
    p = AxisParams(1.0, 5.0, 50.0)
    u = np.full(len(t), 10.0)
    assert abs(simulate_axis(t, u, p, EffectSet(actuator_saturation=4.0))[-1] - 4 / 50) < 1e-6
    assert abs(simulate_axis(t, u, p, EffectSet(actuator_gain=2.0))[-1] - 20 / 50) < 1e-6
    assert abs(simulate_axis(t, u, p, EffectSet(sensor_offset=0.3))[-1] - (0.2 + 0.3)) < 1e-6


def test_series_spring_does_not_change_the_static_balance_but_adds_a_resonance() -> None:
    t = np.arange(0, 20, 0.001)
    p = AxisParams(1.0, 5.0, 50.0)
    u = np.full(len(t), 10.0)
    x = simulate_axis(t, u, p, EffectSet(series_compliance=500.0))
    assert abs(x[-1] - 0.2) < 1e-4


def test_play_operator_holds_for_the_dead_band_after_a_reversal() -> None:
    x = np.concatenate([np.linspace(0, 1, 101), np.linspace(1, 0, 101)[1:]])
    y = play(x, 0.2)
    assert abs(y[100] - 0.9) < 1e-12           # lags the input by half the band going up
    assert np.all(y[100:111] == y[100])         # holds while the gap (0.2) is taken up
    assert abs(y[-1] - 0.1) < 1e-12


def test_noise_estimate_and_whiteness() -> None:
    rng = np.random.default_rng(0)
    t = np.arange(0, 5, 0.001)
    y = np.sin(2 * np.pi * t) + 0.01 * rng.standard_normal(len(t))
    assert abs(noise_std(y) / 0.01 - 1) < 0.1
    ac = autocorr(rng.standard_normal(5000), 10)
    assert ac[0] == 1.0 and np.max(np.abs(ac[1:])) < 0.06


def test_the_compiled_kernel_equals_the_interpreted_loop_bit_for_bit() -> None:
    """The numba kernel is the same source as the interpreted loop: same floats, every branch
    (friction sticking and reversing, series spring, library terms, irregular steps)."""
    from teleop.diagnose import axis_kernel

    rng = np.random.default_rng(11)
    compiled = axis_kernel.kernel()
    assert compiled is not axis_kernel.integrate  # numba is installed: it is compiled
    terms = (("term:sin:25", 0.01), ("term:cos:9", -0.005), ("term:vabsv", -0.002),
             ("term:v3", -0.001), ("term:v2", 0.001), ("term:x2", 0.01), ("term:x3", -0.3))
    for trial in range(6):
        n = 1200
        t = (np.arange(n) * 1e-3 if trial % 2 else
             np.cumsum(rng.uniform(0.7e-3, 2.4e-3, n)))  # irregular: two sub-steps at times
        u = np.cumsum(rng.normal(0, 0.3, n)) * 0.05 + np.sin(7 * t)
        p = AxisParams(inertia=0.02, viscous=0.05, stiffness=2.0, gravity=0.1 * (trial % 3),
                       coulomb=0.03, terms=terms if trial % 4 == 0 else ())
        eff = EffectSet(stiction=0.2 * (trial % 2), asymmetric_friction=0.05,
                        series_compliance=60.0 if trial % 3 == 0 else math.inf)
        fast = simulate_axis(t, u, p, eff, x0=0.01)
        try:
            axis_kernel._COMPILED[:] = [axis_kernel.integrate]
            slow = simulate_axis(t, u, p, eff, x0=0.01)
        finally:
            axis_kernel._COMPILED[:] = [compiled]
        assert np.isfinite(fast).all(), trial
        assert np.array_equal(fast, slow), trial
