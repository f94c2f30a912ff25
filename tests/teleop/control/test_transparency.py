"""Transparency layer: set-point map, maximum (not mean) pressure per finger, force path."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from teleop.config.control import ControllerConfig, TransparencyConfig
from teleop.control.interface import control_params
from teleop.control.transparency_layer import (
    TransparencyState,
    combined_force_n,
    grip_to_setpoints,
    lowpass,
    max_pressures,
    transparency_force,
)
from teleop.messages import FingerState

P = control_params(ControllerConfig())


def finger(pressure: tuple[float, ...]) -> FingerState:
    return FingerState(proximal_rad=0.0, distal_rad=0.0, motor_angle_rad=0.0, load_units=0.0,
                       pressure=pressure, contact=tuple(v > 0 for v in pressure))


def test_setpoint_map_ends_and_disabled_fingers() -> None:
    assert grip_to_setpoints(0.0, P) == (0.0, 0.0, 0.0)
    assert grip_to_setpoints(0.025, P) == (3.0, 3.0, 3.0)
    assert grip_to_setpoints(0.1, P) == (3.0, 3.0, 3.0)  # clipped beyond the travel
    assert grip_to_setpoints(-0.01, P) == (0.0, 0.0, 0.0)
    assert grip_to_setpoints(math.nan, P) == (0.0, 0.0, 0.0)
    assert grip_to_setpoints(0.0125, P) == pytest.approx((1.5, 1.5, 1.5))
    cfg = ControllerConfig(transparency=TransparencyConfig(finger_enable=(True, False, True),
                                                           map_exponent=2.0,
                                                           open_angle_rad=0.5))
    p = control_params(cfg)
    assert grip_to_setpoints(0.0125, p) == pytest.approx((0.5 + 2.5 * 0.25, 0.5,
                                                          0.5 + 2.5 * 0.25))


def test_force_uses_the_maximum_pressure_of_each_finger() -> None:
    # a cylinder loads two of nine cells: the average would show a ninth of the contact
    fingers = (finger((0, 0, 300, 40, 0, 0, 0, 0, 0)), finger((0,) * 9),
               finger((0, 100, 0, 0, 0, 0, 0, 0, -20)))
    assert max_pressures(fingers, P) == (300, 0, 100)
    assert combined_force_n((300, 0, 100), P) == pytest.approx(300 * 0.02)
    mean_p = replace(P, force_combine="mean")
    assert combined_force_n((300, 0, 100), mean_p) == pytest.approx(400 / 3 * 0.02)
    sum_p = replace(P, force_combine="sum")
    assert combined_force_n((300, 0, 100), sum_p) == pytest.approx(400 * 0.02)
    off = replace(P, finger_enable=(False, True, True))
    assert max_pressures(fingers, off) == (0, 0, 100)


def test_force_is_filtered_and_clipped() -> None:
    big = (finger((500,) * 9),) * 3
    st = TransparencyState()
    st, f, _, raw = transparency_force(st, P, big, 1e-3)
    assert raw == pytest.approx(10.0)
    assert 0 < f < 8.0
    for _ in range(2000):
        st, f, _, _ = transparency_force(st, P, big, 1e-3)
    assert f == 8.0
    # the first-order filter reaches 1 - 1/e of a step after one time constant
    y = 0.0
    tau = 1 / (2 * math.pi * 20.0)
    n = 1000
    for _ in range(n):
        y = lowpass(y, 1.0, 20.0, tau / n)
    assert y == pytest.approx(1 - math.exp(-1), rel=1e-9)
    st, f, mp, _ = transparency_force(TransparencyState(), P, None, 1e-3)
    assert f == 0.0 and mp == (0.0, 0.0, 0.0)


def test_tactile_noise_band_is_not_displayed_and_the_map_stays_continuous() -> None:
    band = P.pressure_deadband
    assert band > 0
    assert combined_force_n((band, 0.5 * band, 0.0), P) == 0.0  # free-air noise: no force
    # continuous through the band's edges, the plain map from twice the band on
    assert combined_force_n((band + 1e-9, 0, 0), P) == pytest.approx(0.0, abs=1e-9)
    assert combined_force_n((2 * band, 0, 0), P) == pytest.approx(2 * band * 0.02)
    assert combined_force_n((2 * band - 1e-9, 0, 0), P) == pytest.approx(2 * band * 0.02)
    assert combined_force_n((600, 0, 0), P) == pytest.approx(600 * 0.02)
    grid = [combined_force_n((0.01 * k, 0, 0), P) for k in range(4000)]
    assert all(b >= a for a, b in zip(grid, grid[1:], strict=False))  # monotone
    assert max(abs(b - a) for a, b in zip(grid, grid[1:], strict=False)) < 0.001
    off = replace(P, pressure_deadband=0.0)
    assert combined_force_n((3.0, 0, 0), off) == pytest.approx(0.06)
