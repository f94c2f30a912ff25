"""The two-layer hand side with ``hand_port = "servo"``: one-sided servo potential (the tendon
only pulls), closing-only damping credit and the free-motion refund.  The default
environment-port accounting is tested in ``test_object_port.py``."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from teleop.config.control import ControllerConfig
from teleop.control import two_layer
from teleop.control.interface import control_params
from teleop.control.passivity_layer import (
    dissipation_lower_bound_j,
    pspm_project,
    servo_potential_j,
)
from teleop.messages import FingerState, HandCommand, HandMode, Header

P = replace(control_params(ControllerConfig()), hand_port="servo")
K, TMAX = P.servo_stiffness_nm_per_rad, P.servo_torque_max_nm


def finger(x: float, touching: bool = False) -> FingerState:
    p = 100.0 if touching else 0.0
    return FingerState(proximal_rad=x, distal_rad=0.0, motor_angle_rad=x, load_units=0.0,
                       pressure=(p,) + (0.0,) * 8, contact=(touching,) + (False,) * 8)


def command(y: float, total_j: float = 0.0) -> HandCommand:
    return HandCommand(header=Header(seq=1, t_s=0.0, energy_total_j=total_j),
                       finger_setpoint_rad=(y, y, y), preshape_rad=0.0, mode=HandMode.POSITION)


def test_potential_is_one_sided_and_saturating() -> None:
    assert servo_potential_j(-1.0, K, TMAX) == 0.0
    assert math.isclose(servo_potential_j(0.2, K, TMAX), 0.5 * K * 0.04)
    e_s = TMAX / K
    assert math.isclose(servo_potential_j(2.0, K, TMAX), TMAX * (2.0 - 0.5 * e_s))


def test_opening_costs_nothing_with_an_empty_tank() -> None:
    """The regression behind "the hand ignores the trigger": an empty tank must still let the
    fingers open (a set-point below the motor angle stores nothing the tendon can deliver)."""
    y, dp, limited = pspm_project((0.1, 0.1, 0.1), (1.0, 1.0, 1.0), (0.9, 0.9, 0.9), 0.0, K,
                                  TMAX)
    assert y == (0.1, 0.1, 0.1) and not limited and dp <= 0.0


def test_closing_is_still_limited_by_the_tank() -> None:
    y, dp, limited = pspm_project((2.0, 2.0, 2.0), (0.5, 0.5, 0.5), (0.5, 0.5, 0.5), 0.01, K,
                                  TMAX)
    assert limited and dp <= 0.01 + 1e-12
    assert all(0.5 < v < 2.0 for v in y)


def test_only_closing_motion_is_credited() -> None:
    assert dissipation_lower_bound_j((0.1, 0.0, 0.0), (0.0, 0.0, 0.0), 2.0, 0.1) > 0.0
    assert dissipation_lower_bound_j((0.0, 0.0, 0.0), (0.1, 0.1, 0.1), 2.0, 0.1) == 0.0


def _run(touching: bool, refund: bool = True) -> float:
    """Tank gained while a finger in free motion (or in contact) moves 0.02 rad towards a
    set-point held 0.5 rad ahead of it."""
    p = replace(P, free_motion_refund=refund, transfer_fraction=0.0, max_j=100.0,
                servo_max_speed_rad_s=1e6)
    s = two_layer.init_hand(p)
    fs = (finger(0.0, touching),) * 3
    s, _ = two_layer.step_hand(s, p, fs, command(0.5), 0.025)
    s, _ = two_layer.step_hand(s, p, fs, command(0.5), 0.025)
    after_jump = s.ledger.tank_j
    fs = (finger(0.02, touching),) * 3
    s, _ = two_layer.step_hand(s, p, fs, command(0.5), 0.025)
    return s.ledger.tank_j - after_jump


def test_free_motion_refunds_exactly_the_servo_work() -> None:
    gain = _run(touching=False)
    expected = 3 * (servo_potential_j(0.5, K, TMAX) - servo_potential_j(0.48, K, TMAX))
    assert math.isclose(gain, expected, rel_tol=1e-9)


def test_no_refund_in_contact_only_the_damping_credit() -> None:
    gain = _run(touching=True)
    assert math.isclose(gain, 3 * P.servo_damping_nm_s_per_rad * 0.02 ** 2 / 0.025,
                        rel_tol=1e-9)
    assert gain < _run(touching=False)


def test_refund_can_be_switched_off() -> None:
    assert math.isclose(_run(touching=False, refund=False),
                        3 * P.servo_damping_nm_s_per_rad * 0.02 ** 2 / 0.025, rel_tol=1e-9)


def test_a_set_point_ahead_of_its_motor_drops_to_it_at_once() -> None:
    """Coming back, a set-point that ran ahead of a lagging motor drops to the motor in one
    sample (the servo spring's energy only falls); below the motor, and going out, the
    servo's slew rate holds."""
    step = 0.1
    # ahead of the motor (at 0.3) and commanded back to 0.2: to the motor, then slewed on
    assert two_layer.slew((0.2,) * 3, (1.0,) * 3, step, (0.3,) * 3) == pytest.approx((0.3,) * 3)
    # commanded back to 0.5, above the motor: there at once
    assert two_layer.slew((0.5,) * 3, (1.0,) * 3, step, (0.3,) * 3) == pytest.approx((0.5,) * 3)
    # already at or below the motor: the slew rate
    assert two_layer.slew((0.0,) * 3, (0.3,) * 3, step, (0.5,) * 3) == pytest.approx((0.2,) * 3)
    # closing: the slew rate, wherever the motor
    assert two_layer.slew((2.0,) * 3, (1.0,) * 3, step, (0.3,) * 3) == pytest.approx((1.1,) * 3)
    # without the motor angle (the servo-spring layer, tdpa): the slew rate both ways
    assert two_layer.slew((0.2,) * 3, (1.0,) * 3, step) == pytest.approx((0.9,) * 3)
