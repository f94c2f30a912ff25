"""Stability/passivity metrics on synthetic signals with known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from teleop.analysis.stability import (
    RunSignals,
    StabilityCriteria,
    classify_run,
    delayed,
    energy_generated_j,
    oscillation_metrics,
    rms_error,
)

DT = 1e-3
T = np.arange(0.0, 6.0, DT)


def grasp_script(t: np.ndarray) -> np.ndarray:
    """A raised-cosine close (1 s), hold (2 s), release (1 s) of 0..3 rad: the operator part."""
    cyc = np.fmod(t, 4.5) - 0.5
    s = np.where(cyc < 0, 0.0,
                 np.where(cyc < 1, 0.5 - 0.5 * np.cos(np.pi * cyc),
                          np.where(cyc < 3, 1.0,
                                   np.where(cyc < 4, 0.5 + 0.5 * np.cos(np.pi * (cyc - 3)), 0.0))))
    return 3.0 * s


def signals(setpoint: np.ndarray, force: np.ndarray, **kw: object) -> RunSignals:
    base = dict(t_s=T, setpoint_rad=setpoint, finger_rad=setpoint, force_displayed_n=force,
                force_measured_n=force, energy_out_j=np.zeros_like(T),
                energy_in_j=np.zeros_like(T), tank_j=np.ones((len(T), 2)))
    base.update(kw)
    return RunSignals(**base)  # type: ignore[arg-type]


def test_smooth_operator_motion_is_stable() -> None:
    sp = grasp_script(T)
    force = 2.0 * sp / 3.0
    m = classify_run(signals(sp, force))
    assert m.stable, m.reason
    assert m.oscillation_index < 0.01


def test_decaying_contact_transient_is_stable() -> None:
    sp = grasp_script(T)
    ring = 0.5 * np.exp(-(T - 1.0) / 0.1) * np.sin(2 * np.pi * 8 * (T - 1.0)) * (T > 1.0)
    m = classify_run(signals(sp, 2.0 * sp / 3.0 + ring))
    assert m.stable, m.reason


def test_sustained_limit_cycle_is_unstable() -> None:
    """Constant-amplitude oscillation (a saturated unstable loop) is not stable."""
    sp = grasp_script(T)
    force = np.clip(2.0 * sp / 3.0 + 1.5 * np.sin(2 * np.pi * 3.0 * T), 0, 8)
    m = classify_run(signals(sp, force))
    assert not m.stable
    assert "sustained displayed force" in m.reason


def test_growing_oscillation_is_unstable() -> None:
    """Small but growing (e-fold 1 s) oscillation is caught before it is large."""
    sp = grasp_script(T) + 0.002 * np.exp(T / 1.0) * np.sin(2 * np.pi * 6.0 * T)
    m = classify_run(signals(sp, np.zeros_like(T)))
    assert not m.stable
    assert m.growth_ratio > 2.0


def test_nan_is_unstable() -> None:
    sp = grasp_script(T)
    sp[3000] = math.nan
    m = classify_run(signals(sp, np.zeros_like(T)))
    assert not m.stable and "non-finite" in m.reason


def test_hf_power_fraction() -> None:
    x = np.sin(2 * np.pi * 20 * T)
    assert oscillation_metrics(T, x, 1.0).hf_power_fraction > 0.99
    x = np.sin(2 * np.pi * 3 * T)
    assert oscillation_metrics(T, x, 1.0).hf_power_fraction < 0.05


def test_non_uniform_sampling_matches_uniform() -> None:
    rng = np.random.default_rng(1)
    t = np.sort(rng.uniform(0, 6, 5000))
    x = np.sin(2 * np.pi * 10 * t)
    m = oscillation_metrics(t, x, 1.0)
    assert m.late_rms == pytest.approx(1 / math.sqrt(2), rel=0.05)


def test_passive_when_energy_out_within_budget() -> None:
    e_in = np.linspace(0, 2.0, len(T))
    e_out = e_in + 0.5  # delivered the 0.5 J the tanks started with, no more
    s = signals(grasp_script(T), np.zeros_like(T), energy_out_j=e_out, energy_in_j=e_in,
                initial_energy_j=0.5)
    m = classify_run(s)
    assert m.passive
    assert m.energy_generated_j == pytest.approx(0.0, abs=1e-12)


def test_generated_energy_detected() -> None:
    e_in = np.linspace(0, 2.0, len(T))
    e_out = e_in + 0.5 + 0.01 * T  # 60 mJ more than stored by the end
    s = signals(grasp_script(T), np.zeros_like(T), energy_out_j=e_out, energy_in_j=e_in,
                initial_energy_j=0.5)
    m = classify_run(s)
    assert not m.passive
    assert m.energy_generated_j == pytest.approx(0.01 * T[-1], rel=1e-6)
    assert energy_generated_j(e_out, e_in, 0.5) == m.energy_generated_j


def test_tracking_against_delayed_command() -> None:
    """A hand that follows the command exactly d late has zero tracking error."""
    cmd = grasp_script(T)
    d = 0.25
    hand = delayed(T, cmd, d)
    assert rms_error(T, hand, cmd, d) == pytest.approx(0.0, abs=1e-9)
    assert rms_error(T, hand, cmd, 0.0) > 0.1
    s = signals(cmd, np.zeros_like(T), finger_rad=hand, forward_delay_s=d)
    assert classify_run(s).tracking_rms_rad < 1e-9


def test_force_rms_and_tank_and_limits() -> None:
    meas = np.full_like(T, 2.0)
    disp = meas + 0.1
    tank = np.column_stack([np.linspace(1, 0.2, len(T)), np.ones_like(T)])
    s = signals(grasp_script(T), disp, force_measured_n=meas, tank_j=tank, limited_count=30,
                steps=6000)
    m = classify_run(s)
    assert m.force_rms_n == pytest.approx(0.1)
    assert m.tank_min_j == pytest.approx(0.2, rel=1e-3)
    assert m.limited_fraction == pytest.approx(0.005)


def test_criteria_are_tunable() -> None:
    sp = grasp_script(T) + 0.06 * np.sin(2 * np.pi * 4 * T)  # 1.4 % of the 3 rad scale
    assert classify_run(signals(sp, np.zeros_like(T))).stable
    strict = StabilityCriteria(sustained_fraction=0.005)
    assert not classify_run(signals(sp, np.zeros_like(T)), strict).stable
