"""``teleop sweep`` command line: one-line errors, signal adapters, the linearised-loop mapping."""

from __future__ import annotations

import math

import numpy as np
import pytest

from teleop.analysis.direct_limit import HandLinearisation, direct_loop_params, intrinsic_delay_s
from teleop.analysis.sweep_live import signals_from_recordings
from teleop.analysis.sweep_signals import fill_nan, measured_force_n, settle_time_s
from teleop.cli import main
from teleop.config import TeleopConfig, load_config
from teleop.control.stability_limit import loop_gain
from teleop.recording import Recording


@pytest.mark.parametrize("argv, needle", [
    (["--delays", "0,abc"], "--delays: 'abc' is not a number"),
    (["--losses", "1.5"], "--losses: loss probabilities must be within [0, 1]"),
    (["--controllers", "two-layer,bogus"], "unknown controller 'bogus'"),
    (["--set", "nope.key=1"], "nope"),
    (["--json", "."], "is a directory"),  # refused before the runs, not after them
    (["--rerun", "."], "is a directory"),
])
def test_bad_input_is_one_line_exit_2(argv: list[str], needle: str, capsys) -> None:
    assert main(["sweep", "--no-progress", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0]


def test_fill_nan_forward_fills() -> None:
    x = np.array([np.nan, np.nan, 1.0, np.nan, 3.0, np.nan])
    assert fill_nan(x).tolist() == [1.0, 1.0, 1.0, 1.0, 3.0, 3.0]
    assert fill_nan(x, before=0.0).tolist() == [0.0, 0.0, 1.0, 1.0, 3.0, 3.0]


def test_measured_force_combines_like_the_transparency_layer() -> None:
    cfg = TeleopConfig()  # max of per-finger maxima, 0.02 N per unit, clipped at 8 N
    p = np.zeros((2, 27))
    p[0, 3], p[0, 12] = 100.0, 250.0  # finger 1 sensor 3, finger 2 sensor 3
    p[1, 20] = 1000.0  # finger 3, beyond the trigger's force limit
    f = measured_force_n(p, cfg)
    assert f[0] == pytest.approx(5.0) and f[1] == pytest.approx(8.0)


def test_settle_time_is_ramp_end_plus_round_trip() -> None:
    cfg = load_config(None, ["master.virtual.repeat=false", "links.master_controller.delay_s=0.1"])
    v = cfg.master.virtual
    assert settle_time_s(cfg) == pytest.approx(v.close_s + v.ramp_s + 0.2 + 1 / 40)
    assert settle_time_s(TeleopConfig()) == 0.0  # a repeating script never holds still


def test_loop_params_reproduce_the_identified_hand() -> None:
    """The servo/contact form of P_s keeps the identified DC gain and time constant."""
    cfg = TeleopConfig()
    hand = HandLinearisation(0.5, 250.0, 900.0, 0.9, 0.3)
    lp = direct_loop_params(cfg, hand, operator_stiffness_n_per_m=500.0,
                            operator_damping_n_s_per_m=6.0, servo_stiffness_nm_per_rad=4.9)
    g = 3.0 / 0.025
    assert abs(loop_gain(lp, 1e-9)) == pytest.approx(g * 900.0 * 0.02 / 500.0, rel=1e-6)
    k, ke = lp.servo_stiffness_nm_per_rad, lp.contact_stiffness_nm_per_rad
    assert lp.servo_damping_nm_s_per_rad / (k + ke) == pytest.approx(0.3)
    assert k / (k + ke) == pytest.approx(0.9)
    assert intrinsic_delay_s(cfg) == pytest.approx(1 / 40 + 2e-3)


def _rec(t: np.ndarray, **cols: object) -> Recording:
    return Recording.from_columns({"t_s": t, **{k: np.broadcast_to(np.asarray(v, float), t.shape)
                                               for k, v in cols.items()}})


def test_live_recordings_merge_and_initial_energy() -> None:
    """Hand/controller held on the master's clock; initial tank energy from the ledger identity."""
    tm = np.arange(0.0, 1.0, 0.001) + 5.0
    th = np.arange(0.0, 1.0, 0.025) + 5.0
    master = _rec(tm, displayed_force_n=1.0, port_out_j=0.0, port_in_j=0.0, tank_j=9.0,
                  sent_j=1.0, received_j=0.0, dissipated_j=0.0, limit_count=0.0, dropped=0.0)
    hand_cols = {f"pressure_f{i // 9 + 1}_{i % 9}": 50.0 for i in range(27)}
    hand_cols |= {f"motor_angle_rad_f{i}": 0.5 for i in (1, 2, 3)}
    hand = _rec(th, port_out_j=0.0, port_in_j=0.0, tank_j=10.5, sent_j=0.0, received_j=0.5,
                dissipated_j=0.0, limit_count=0.0, dropped=0.0, **hand_cols)
    ctrl_cols = {f"setpoint_rad_f{i}": 0.5 for i in (1, 2, 3)}
    ctrl = _rec(tm, store_j=0.5, sent_j=0.5, received_j=1.0, dissipated_j=0.0,
                master_dropped=0.0, hand_dropped=0.0, **ctrl_cols)
    s = signals_from_recordings(master, ctrl, hand, TeleopConfig())
    assert s.initial_energy_j == pytest.approx(20.0)
    assert s.t_s[0] == 0.0 and len(s.t_s) == len(tm)
    assert np.allclose(s.force_measured_n, 1.0) and np.allclose(s.finger_rad, 0.5)
    assert math.isclose(s.tank_j.min(), 9.0)
