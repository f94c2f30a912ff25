"""Every catalog effect changes the simulated recording in the physically expected direction."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest

from sim.experiments import ExperimentSpec, run_experiment
from sim.finger import ContactObject, default_finger_params
from teleop.effects import EFFECT_NAMES, EffectSet, parse_effects
from teleop.recording import Recording

P = default_finger_params()
NONE = ContactObject()


@lru_cache(maxsize=32)
def _force_step(items: tuple[str, ...]) -> Recording:
    return run_experiment(ExperimentSpec("force-step", duration_s=10.0), P, NONE,
                          parse_effects(list(items))).recording


@lru_cache(maxsize=32)
def _position(items: tuple[str, ...]) -> Recording:
    return run_experiment(ExperimentSpec("position", duration_s=4.0), P, NONE,
                          parse_effects(list(items))).recording


def _end(rec: Recording, col: str) -> float:
    return float(rec.column(col)[-1])


def _at(rec: Recording, col: str, t: float) -> float:
    return float(rec.column(col)[rec.t_s.searchsorted(t)])


def _track_rms(rec: Recording) -> float:
    err = rec.column("joint_angle_rad") - rec.column("setpoint_rad")
    return float(np.sqrt(np.mean(err ** 2)))


BASE: tuple[str, ...] = ()


def test_dead_time_delays_the_response() -> None:
    fx = ("dead_time=0.2",)
    assert _at(_force_step(fx), "motor_angle_rad", 2.0) < _at(_force_step(BASE),
                                                              "motor_angle_rad", 2.0) - 0.005
    assert _track_rms(_position(fx)) > _track_rms(_position(BASE)) + 0.05


@pytest.mark.parametrize("item", ["coulomb_friction=2", "asymmetric_friction=2", "stiction=3"])
def test_friction_slows_force_mode_closing(item: str) -> None:
    fx = (item,)
    assert _end(_force_step(fx), "motor_angle_rad") < _end(_force_step(BASE),
                                                           "motor_angle_rad") - 0.05


def test_asymmetric_friction_acts_only_when_pulling() -> None:
    # identical to Coulomb while the motor only moves forwards...
    a = _force_step(("asymmetric_friction=2",)).column("motor_angle_rad")
    c = _force_step(("coulomb_friction=2",)).column("motor_angle_rad")
    assert np.allclose(a, c, atol=1e-4)
    # ...but less tracking error than symmetric Coulomb in a back-and-forth position move
    # (the deterministic runs differ by ~8e-4 rad: identical friction would fail this)
    assert _track_rms(_position(("asymmetric_friction=2",))) < _track_rms(
        _position(("coulomb_friction=2",))) - 4e-4


def test_backlash_makes_the_motor_travel_further_for_the_same_pose() -> None:
    fx = ("backlash=0.1",)
    assert _end(_force_step(fx), "motor_angle_rad") > _end(_force_step(BASE), "motor_angle_rad")
    assert (_position(fx).column("proximal_angle_rad").mean()
            < _position(BASE).column("proximal_angle_rad").mean() - 0.01)


def test_actuator_saturation_caps_the_load() -> None:
    rec = _position(("actuator_saturation=5",))
    assert np.abs(rec.column("motor_load_units")).max() <= 5.0 * P.units_per_n + 1e-9
    assert np.abs(_position(BASE).column("motor_load_units")).max() > 100.0


def test_actuator_gain_scales_the_effort() -> None:
    rec = _force_step(("actuator_gain=0.5",))
    assert rec.column("motor_load_units").max() == pytest.approx(30.0)
    assert _end(rec, "proximal_angle_rad") < _end(_force_step(BASE), "proximal_angle_rad")


def test_actuator_lag_slows_the_effort() -> None:
    fx = ("actuator_lag=0.5",)
    rec = _force_step(fx)
    assert _at(rec, "motor_load_units", 1.25) < 0.6 * 60.0
    assert _at(rec, "motor_angle_rad", 2.0) < _at(_force_step(BASE), "motor_angle_rad", 2.0)


def test_sensor_offset_shifts_measured_angles() -> None:
    rec = _force_step(("sensor_offset=0.1",))
    base = _force_step(BASE)
    assert np.allclose(rec.column("motor_angle_rad") - base.column("motor_angle_rad"), 0.1)
    assert np.allclose(rec.column("proximal_angle_rad") - base.column("proximal_angle_rad"),
                       0.1)


def test_series_compliance_stretches_between_motor_and_finger() -> None:
    fx = ("series_compliance=50",)
    assert _end(_force_step(fx), "motor_angle_rad") > _end(_force_step(BASE), "motor_angle_rad")
    assert (_position(fx).column("proximal_angle_rad").mean()
            < _position(BASE).column("proximal_angle_rad").mean() - 0.02)


@pytest.mark.parametrize("item", ["nonlinear_stiffness=20", "gravity=4"])
def test_stiffening_and_gravity_hold_the_finger_back(item: str) -> None:
    fx = (item,)
    assert (_position(fx).column("proximal_angle_rad").mean()
            < _position(BASE).column("proximal_angle_rad").mean() - 0.01)
    assert _end(_force_step(fx), "proximal_angle_rad") <= _end(_force_step(BASE),
                                                               "proximal_angle_rad")


def test_every_catalog_effect_is_covered() -> None:
    covered = {"dead_time", "coulomb_friction", "asymmetric_friction", "stiction", "backlash",
               "actuator_saturation", "actuator_gain", "actuator_lag", "sensor_offset",
               "series_compliance", "nonlinear_stiffness", "gravity"}
    assert covered == set(EFFECT_NAMES)
    assert EffectSet().active() == ()
