"""The touch caps of model-mediated rendering (:mod:`teleop.control.touch_cap`): a finger's
new touch is held where the model renders a light touch until the controller (hand side) and
the operator (controller side) know of it."""

from __future__ import annotations

import math

from teleop.config.control import ControllerConfig
from teleop.control import touch_cap
from teleop.control.contact_model import FingerModel
from teleop.control.interface import control_params
from teleop.messages import HandCommand, HandMode, Header, MasterState

P = control_params(ControllerConfig())
NAN3 = (math.nan,) * 3


def master(echo_t_s: float, t_s: float = 0.0, held_s: float = 0.0) -> MasterState:
    return MasterState(header=Header(seq=1, t_s=t_s, energy_total_j=0.0),
                       grip_position_m=0.02, grip_velocity_m_s=0.0, echo_t_s=echo_t_s,
                       echo_held_s=held_s)


def hand_command(sp: tuple[float, float, float], echo_t_s: float) -> HandCommand:
    return HandCommand(header=Header(seq=1, t_s=0.0, energy_total_j=0.0),
                       finger_setpoint_rad=sp, preshape_rad=0.0, mode=HandMode.POSITION,
                       hand_echo_t_s=echo_t_s)


def test_a_new_touch_is_capped_until_the_operator_can_have_felt_it() -> None:
    sp = (2.0, 2.0, 0.1)
    model = (0.4, 40.0, 0.4, 40.0, 0.0, 0.0)  # fingers 1, 2 touching; finger 3 not
    f_touch = touch_cap.touch_force_n(P)
    assert 0.0 < f_touch < P.force_max_n  # a light touch, below the trigger's largest force
    cap = 0.4 + f_touch / 40.0
    feel = touch_cap.feel_time_s(P)
    assert feel > 0.0
    since, felt, out = touch_cap.unseen_touch_cap(NAN3, P, model, master(-1.0, 100.0), sp, 5.0)
    assert since[:2] == (5.0, 5.0) and math.isnan(since[2]) and all(map(math.isnan, felt))
    assert out == (cap, cap, 0.1)
    # later, the master still echoes a command from before the model: still capped
    since, felt, out = touch_cap.unseen_touch_cap(since, P, model, master(4.99, 100.4), sp,
                                                  5.4, felt)
    assert since[:2] == (5.0, 5.0) and out[:2] == (cap, cap)
    # it echoes the command that carried the model, received 0.02 s ago on the master's
    # clock: the operator has felt the touch for 0.02 s only, his trigger still shows the
    # blind squeeze: still capped
    since, felt, out = touch_cap.unseen_touch_cap(since, P, model, master(5.0, 100.5, 0.02),
                                                  sp, 5.5, felt)
    assert felt[:2] == (100.48, 100.48) and out[:2] == (cap, cap)
    # a master state from feel_s after it got the model: the operator decides again
    t_m = 100.48 + feel + 1e-9
    since, felt, out = touch_cap.unseen_touch_cap(since, P, model, master(5.2, t_m - 2e-3),
                                                  sp, 5.6, felt)
    assert out[:2] == (cap, cap)
    since, felt, out = touch_cap.unseen_touch_cap(since, P, model, master(5.2, t_m), sp, 5.7,
                                                  felt)
    assert out == sp
    # the touch ends (model withdrawn) and a new one starts: capped again until felt
    since, felt, _ = touch_cap.unseen_touch_cap(since, P, (0.0,) * 6, master(5.5, t_m), sp,
                                                6.0, felt)
    assert all(math.isnan(v) for v in since + felt)
    since, felt, out = touch_cap.unseen_touch_cap(since, P, model, master(6.0, t_m + 1.0), sp,
                                                  6.1, felt)
    assert out[:2] == (cap, cap)


TOUCH = FingerModel(contact_rad=0.3, stiffness=600.0)  # pressure units per rad
FREE = FingerModel()


def test_the_hand_records_when_each_finger_s_model_became_valid() -> None:
    since = touch_cap.touch_since(NAN3, (TOUCH, FREE, TOUCH), 2.0)
    assert since[0] == since[2] == 2.0 and math.isnan(since[1])
    since = touch_cap.touch_since(since, (TOUCH, TOUCH, FREE), 2.5)  # kept; new; dropped
    assert since[0] == 2.0 and since[1] == 2.5 and math.isnan(since[2])
    assert all(math.isnan(v) for v in touch_cap.touch_since(NAN3, (TOUCH,) * 3, math.nan))
    assert all(math.isnan(v) for v in touch_cap.touch_since((1.0,) * 3, None, 3.0))


def test_the_hand_caps_a_touch_the_controller_had_not_seen() -> None:
    models = (TOUCH, TOUCH, FREE)
    since = (2.0, 2.0, math.nan)
    cap = 0.3 + touch_cap.touch_force_n(P) / (600.0 * P.force_per_pressure_n)
    # computed from a hand state before the touch: fingers 1 and 2 capped, 3 has no model
    out = touch_cap.hand_touch_cap(P, models, since, hand_command((3.0, 0.2, 3.0), 1.99))
    assert out is not None
    assert out.finger_setpoint_rad == (cap, 0.2, 3.0)  # finger 2 is below its cap already
    assert out.hand_echo_t_s == 1.99
    # computed from the state that carried the touch: the controller's own cap decides
    cmd = hand_command((3.0, 3.0, 3.0), 2.0)
    assert touch_cap.hand_touch_cap(P, models, since, cmd) is cmd
    # nothing binds: the same command, not a copy
    low = hand_command((0.1, 0.1, 0.1), -1.0)
    assert touch_cap.hand_touch_cap(P, models, since, low) is low
    assert touch_cap.hand_touch_cap(P, None, since, cmd) is cmd
    assert touch_cap.hand_touch_cap(P, models, since, None) is None


def test_the_hand_holds_a_pressed_unseen_touch_where_its_motor_is() -> None:
    """The model's stiffness is a prior on a first touch; once a finger's measured pressure
    renders the touch force the hand holds it at its motor angle, wherever the model's cap."""
    models = (FingerModel(contact_rad=0.3, stiffness=50.0),) * 3  # far too soft a prior
    since = (2.0, 2.0, 2.0)
    p_touch = touch_cap.touch_force_n(P) / P.force_per_pressure_n
    cmd = hand_command((3.0, 3.0, 3.0), 1.0)
    out = touch_cap.hand_touch_cap(P, models, since, cmd, (p_touch, p_touch - 1.0, 0.0),
                                   (0.35, 0.36, 0.2))
    assert out is not None
    model_cap = 0.3 + touch_cap.touch_force_n(P) / (50.0 * P.force_per_pressure_n)
    assert out.finger_setpoint_rad == (0.35, model_cap, model_cap)
    # once the controller has seen the touch the hand no longer holds it
    seen = hand_command((3.0, 3.0, 3.0), 2.0)
    assert touch_cap.hand_touch_cap(P, models, since, seen, (1e4,) * 3, (0.35,) * 3) is seen


def test_a_cap_only_lowers_a_set_point() -> None:
    """Property over a grid: the capped set-point never exceeds the commanded one (the cap
    adds no energy) and never goes below contact."""
    for sp in (0.0, 0.31, 0.8, 1.5, 3.0):
        for k in (50.0, 600.0, 20000.0):
            m = (FingerModel(contact_rad=0.3, stiffness=k),) * 3
            out = touch_cap.hand_touch_cap(P, m, (1.0,) * 3, hand_command((sp,) * 3, 0.5))
            assert out is not None
            for v in out.finger_setpoint_rad:
                assert v <= sp and (v >= 0.3 or v == sp)
