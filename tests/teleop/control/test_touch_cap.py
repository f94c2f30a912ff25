"""The touch caps of model-mediated rendering (:mod:`teleop.control.touch_cap`): a finger's
new touch is held where the model renders the trigger's largest force until the controller
(hand side) and the master (controller side) know of it."""

from __future__ import annotations

import math

from teleop.config.control import ControllerConfig
from teleop.control import touch_cap
from teleop.control.contact_model import FingerModel
from teleop.control.interface import control_params
from teleop.messages import HandCommand, HandMode, Header, MasterState

P = control_params(ControllerConfig())
NAN3 = (math.nan,) * 3


def master(echo_t_s: float) -> MasterState:
    return MasterState(header=Header(seq=1, t_s=0.0, energy_total_j=0.0),
                       grip_position_m=0.02, grip_velocity_m_s=0.0, echo_t_s=echo_t_s)


def hand_command(sp: tuple[float, float, float], echo_t_s: float) -> HandCommand:
    return HandCommand(header=Header(seq=1, t_s=0.0, energy_total_j=0.0),
                       finger_setpoint_rad=sp, preshape_rad=0.0, mode=HandMode.POSITION,
                       hand_echo_t_s=echo_t_s)


def test_a_new_touch_is_capped_until_the_master_has_seen_its_model() -> None:
    sp = (2.0, 2.0, 0.1)
    model = (0.4, 40.0, 0.4, 40.0, 0.0, 0.0)  # fingers 1, 2 touching; finger 3 not
    cap = 0.4 + P.force_max_n / 40.0
    since, out = touch_cap.unseen_touch_cap(NAN3, P, model, master(-1.0), sp, 5.0)
    assert since[:2] == (5.0, 5.0) and math.isnan(since[2])
    assert out == (cap, cap, 0.1)
    # later, the master still echoes a command from before the model: still capped
    since, out = touch_cap.unseen_touch_cap(since, P, model, master(4.99), sp, 5.4)
    assert since[:2] == (5.0, 5.0) and out[:2] == (cap, cap)
    # it echoes the command that carried the model: the operator decides again
    since, out = touch_cap.unseen_touch_cap(since, P, model, master(5.0), sp, 5.5)
    assert out == sp
    # the touch ends (model withdrawn) and a new one starts: capped again until seen
    since, _ = touch_cap.unseen_touch_cap(since, P, (0.0,) * 6, master(5.5), sp, 6.0)
    assert all(math.isnan(v) for v in since)
    since, out = touch_cap.unseen_touch_cap(since, P, model, master(6.0), sp, 6.1)
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
    cap = 0.3 + P.force_max_n / (600.0 * P.force_per_pressure_n)
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
