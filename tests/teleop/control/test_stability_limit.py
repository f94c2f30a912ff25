"""The predicted stability limit of direct control against a time-domain simulation of the
same linear delayed loop."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from teleop.control.stability_limit import (
    DirectLoopParams,
    crossovers_rad_s,
    loop_gain,
    predicted_max_stable_delay_s,
    zero_delay_stable,
)


def simulate_growth(p: DirectLoopParams, delay_s: float, t_end: float = 3.0) -> float:
    """Ratio of late to early oscillation amplitude of the linear loop after a kick."""
    h = 2e-5
    n = int(t_end / h)
    nd = max(1, int(round(delay_s / h)))
    x = v = 0.0
    th = 0.0  # contact torque state (first-order servo against contact)
    ff = 0.0  # filtered force
    wf = 2 * math.pi * p.filter_hz if p.filter_hz else None
    buf = np.zeros(nd)
    xs = np.empty(n)
    k_s, b_s, ke = (p.servo_stiffness_nm_per_rad, p.servo_damping_nm_s_per_rad,
                    p.contact_stiffness_nm_per_rad)
    for i in range(n):
        y = p.position_gain_rad_per_m * buf[i % nd]  # delayed set-point
        buf[i % nd] = x
        # servo: B thdot = K (y - th) - ke th; contact torque ke * th
        th += h * (k_s * (y - th) - ke * th) / b_s
        f = p.force_gain_n_per_nm * ke * th
        if wf is None:
            ff = f
        else:
            ff += h * wf * (f - ff)
        a = (-p.stiffness_n_per_m * x - p.damping_n_s_per_m * v - ff
             + (1.0 if i * h < 0.002 else 0.0)) / p.mass_kg
        v += h * a
        x += h * v
        xs[i] = x
    q = n // 3
    return float(np.abs(xs[-q:]).max() / max(np.abs(xs[q:2 * q]).max(), 1e-30))


@pytest.mark.parametrize("filter_hz", [20.0, None])
def test_prediction_matches_linear_simulation(filter_hz: float | None) -> None:
    p = DirectLoopParams(force_gain_n_per_nm=4.0, servo_stiffness_nm_per_rad=13.0,
                         servo_damping_nm_s_per_rad=0.8, filter_hz=filter_hz)
    t_max = predicted_max_stable_delay_s(p)
    assert 0.005 < t_max < 0.1
    # the delayed round trip's phase at crossover reaches -pi exactly at t_max
    wc = min(crossovers_rad_s(p), key=lambda w: ((math.pi + np.angle(loop_gain(p, w)))
                                                  % (2 * math.pi)) / w)
    assert math.isclose(abs(loop_gain(p, wc)), 1.0, rel_tol=1e-6)
    assert simulate_growth(p, 0.8 * t_max) < 1.0  # decays
    assert simulate_growth(p, 1.2 * t_max) > 1.0  # grows


def test_small_loop_gain_is_stable_for_any_delay() -> None:
    p = DirectLoopParams(force_gain_n_per_nm=0.5)
    assert zero_delay_stable(p)
    assert predicted_max_stable_delay_s(p) == math.inf


def test_unstable_without_delay_gives_zero() -> None:
    p = replace(DirectLoopParams(), force_gain_n_per_nm=50.0, damping_n_s_per_m=0.1)
    assert not zero_delay_stable(p)
    assert predicted_max_stable_delay_s(p) == 0.0


def test_stiffer_contact_lowers_the_limit() -> None:
    soft = DirectLoopParams(force_gain_n_per_nm=4.0, servo_stiffness_nm_per_rad=13.0,
                            contact_stiffness_nm_per_rad=2.0, filter_hz=None)
    stiff = replace(soft, contact_stiffness_nm_per_rad=6.0)
    assert predicted_max_stable_delay_s(stiff) < predicted_max_stable_delay_s(soft)


def test_loop_params_from_config_uses_the_transparency_map() -> None:
    from teleop.config.control import ControllerConfig
    from teleop.control.stability_limit import loop_params_from_config

    p = loop_params_from_config(ControllerConfig(), mass_kg=0.05, damping_n_s_per_m=6.0,
                                stiffness_n_per_m=500.0, contact_stiffness_nm_per_rad=3.2,
                                pressure_per_nm=200.0, servo_damping_nm_s_per_rad=0.8)
    assert p.position_gain_rad_per_m == 120.0
    assert p.force_gain_n_per_nm == 4.0
    assert predicted_max_stable_delay_s(p) == pytest.approx(
        predicted_max_stable_delay_s(DirectLoopParams(servo_damping_nm_s_per_rad=0.8,
                                                      force_gain_n_per_nm=4.0)))
