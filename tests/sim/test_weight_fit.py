"""Table 4.2's two columns: the base-spring fits and the simulated weight test on each."""

from __future__ import annotations

import json

import pytest

from sim.finger import default_finger_params, weight_equilibrium
from sim.params import TABLE_4_2_MEASURED, TABLE_4_2_MODEL, fit_base_spring
from sim.sim_hand import SimHand
from teleop.cli import main
from teleop.config import load_config


def test_the_model_column_fit_is_the_line_through_its_two_lifted_points() -> None:
    fit = fit_base_spring(TABLE_4_2_MODEL)
    assert fit.rad_per_n == pytest.approx((2.407 - 0.767) / (15.7 - 9.8))
    assert fit.residual_rad == pytest.approx((0.0,) * 4, abs=1e-12)
    assert 6.9 < fit.threshold_n < 9.8  # the finger stays on its stop at 6.9 N


def test_the_measured_column_fit_lifts_the_finger_before_6_9_n() -> None:
    fit = fit_base_spring(TABLE_4_2_MEASURED)
    assert 4.9 < fit.threshold_n < 6.9  # 0.087 rad at 6.9 N: the corner is below it
    assert fit.threshold_n < fit_base_spring(TABLE_4_2_MODEL).threshold_n
    assert max(abs(r) for r in fit.residual_rad) < 0.035 and fit.rms_rad < 0.02
    assert fit.predicted_rad[3] == 0.0  # and still on the stop at 4.9 N


def test_a_zero_row_the_line_would_lift_joins_the_fit() -> None:
    fit = fit_base_spring(((10.0, 2.0), (8.0, 1.0), (6.0, 0.0), (7.5, 0.0)))
    alone = fit_base_spring(((10.0, 2.0), (8.0, 1.0), (6.0, 0.0)))  # 7.5 N -> 0.75 rad
    assert alone.rad_per_n == pytest.approx(0.5) and alone.threshold_n == pytest.approx(6.0)
    assert fit.predicted_rad[3] < 0.75 - 0.3  # the zero at 7.5 N pulled the line down
    assert fit.predicted_rad[2] == 0.0
    with pytest.raises(ValueError):
        fit_base_spring(((10.0, 2.0), (5.0, 0.0)))


@pytest.mark.parametrize("calibration", ["model", "measured"])
def test_the_simulated_weight_test_follows_the_chosen_column(calibration: str) -> None:
    table = TABLE_4_2_MODEL if calibration == "model" else TABLE_4_2_MEASURED
    fit = fit_base_spring(table)
    p = default_finger_params(calibration)
    for (force, _), want in zip(table, fit.predicted_rad, strict=True):
        prox, _ = weight_equilibrium(p, force)
        assert prox == pytest.approx(want, abs=2e-3)


def test_the_config_choice_reaches_the_hand_and_the_cli(capsys: pytest.CaptureFixture[str]) \
        -> None:
    cfg = load_config(None, ["hand.sim.calibration=measured"])
    hand = SimHand(cfg.hand)
    assert hand.params.finger.base_preload_rad == fit_base_spring(TABLE_4_2_MEASURED).preload_rad
    assert main(["sim", "weight", "--force-n", "6.9", "--set", "hand.sim.calibration=measured",
                 "--json", "-"]) == 0
    assert json.loads(capsys.readouterr().out)["proximal_angle_rad"] == pytest.approx(
        0.066, abs=3e-3)
