"""The seed report's numbers: Table 4.2 (weight test, model column) and Table 4.1 (motor pull)."""

from __future__ import annotations

import json
import math

import pytest

from sim.experiments import ExperimentSpec, run_experiment
from sim.finger import (
    NO_EFFECTS,
    ContactObject,
    default_finger_params,
    initial_finger_state,
    tendon_stretch_m,
    weight_equilibrium,
)
from sim.params import TABLE_4_1_SLOPES, TABLE_4_2_MODEL
from teleop.cli import main

P = default_finger_params()


@pytest.mark.parametrize(("force_n", "expected_rad"), TABLE_4_2_MODEL)
def test_weight_matches_table_4_2_model_column(force_n: float, expected_rad: float) -> None:
    prox, dist = weight_equilibrium(P, force_n)
    assert prox == pytest.approx(expected_rad, abs=0.05)
    assert 0.0 <= dist < 1.8


def test_weight_cli_json_contract(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", "weight", "--force-n", "9.8", "--json", "-"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert set(data) == {"force_n", "proximal_angle_rad", "distal_angle_rad"}
    assert data["force_n"] == 9.8
    assert data["proximal_angle_rad"] == pytest.approx(0.767, abs=0.05)


@pytest.mark.parametrize(("units", "slope"), TABLE_4_1_SLOPES)
def test_pull_unloaded_matches_table_4_1(units: float, slope: float) -> None:
    res = run_experiment(ExperimentSpec("pull-unloaded", units=units), P, ContactObject(),
                         NO_EFFECTS)
    v = float(res.summary["motor_velocity_rad_s"])
    assert v == pytest.approx(slope, rel=0.15)
    # the tendon is loose: no force reaches the finger
    assert max(res.recording.column("tendon_force_n")) == 0.0


def test_base_equilibrium_matches_hand_calculation() -> None:
    # torque balance on the base joint: F r_b = k_b (phi + preload)
    for force in (8.0, 11.0, 14.0):
        prox, _ = weight_equilibrium(P, force)
        hand = force * P.r_base_m / P.k_base_nm_per_rad - P.base_preload_rad
        assert prox == pytest.approx(hand, abs=1e-4)


def test_flexure_equilibrium_is_virtual_work_balance() -> None:
    # each segment's spring moment equals tension x the tendon's moment arm about it,
    # the arm from a finite difference of the tendon path (eq. 4.4)
    force = 12.0
    prox, dist = weight_equilibrium(P, force)
    from dataclasses import replace

    from sim.finger import hung_weight_step

    st = initial_finger_state(P)
    for _ in range(20000):
        st = hung_weight_step(st, P, force, 1e-3)
    assert st.prox_rad == pytest.approx(prox, abs=1e-3)
    kseg = P.k_flex_segment_nm_per_rad
    h = 1e-7
    for i, s in enumerate(st.flex_rad):
        bumped = list(st.flex_rad)
        bumped[i] = s + h
        arm = -(tendon_stretch_m(replace(st, flex_rad=tuple(bumped)), P)
                - tendon_stretch_m(st, P)) / h
        assert kseg * s == pytest.approx(force * arm, rel=1e-3)
    # four equal series springs: the whole joint is k_seg / 4
    assert math.isclose(P.k_flex_segment_nm_per_rad, 4 * P.k_flex_total_nm_per_rad)
