"""The simulated hand behind the HandBackend interface."""

from __future__ import annotations

from dataclasses import replace

import pytest

from sim.sim_hand import SimHand
from teleop.config import load_config
from teleop.effects import EffectSet
from teleop.messages import N_PRESSURE, HandCommand, HandMode, Header

CFG = load_config(None, [])


def _cmd(sp=(1.0, 1.0, 0.6), pre=0.4, mode=HandMode.POSITION, force=(0.0, 0.0, 0.0)):
    return HandCommand(Header(1, 0.0, 0.0), sp, pre, mode, force)


def _no_object(noise: bool = False):
    obj = replace(CFG.hand.sim.object, kind="none")
    return replace(CFG.hand, sim=replace(CFG.hand.sim, object=obj, noise=noise))


def test_position_mode_tracks_joint_setpoints_and_preshape() -> None:
    hand = SimHand(_no_object(), seed=0)
    hand.start()
    hand.apply(_cmd())
    r = None
    for k in range(1, 161):  # 4 s at 40 Hz
        r = hand.read(k / 40.0)
    assert r is not None and r.t_s == pytest.approx(4.0)
    for f, sp in zip(r.fingers, (1.0, 1.0, 0.6), strict=True):
        assert f.motor_angle_rad == pytest.approx(sp, abs=0.06)
        assert 0.1 < sp - f.proximal_rad < 0.4      # the report's position-mode offset
        assert f.distal_rad == pytest.approx(max(0.0, f.motor_angle_rad - f.proximal_rad))
        assert len(f.pressure) == N_PRESSURE and not any(f.contact)
        assert f.load_units > 0
    assert r.preshape_rad == pytest.approx(0.4, abs=0.02)


def test_grasp_reports_contact_and_safe_open_releases() -> None:
    hand = SimHand(CFG.hand, seed=3)  # default object: a cylinder
    hand.start()
    hand.apply(_cmd(sp=(1.5, 1.5, 1.5)))
    r = hand.read(3.0)
    assert all(any(f.contact) for f in r.fingers)
    hand.safe("open")
    r = hand.read(6.0)
    assert all(not any(f.contact) for f in r.fingers)
    assert all(f.proximal_rad < 0.02 for f in r.fingers)


def test_safe_hold_keeps_the_pose() -> None:
    hand = SimHand(_no_object())
    hand.apply(_cmd(sp=(1.2, 1.2, 1.2)))
    before = hand.read(3.0)
    hand.safe("hold")
    after = hand.read(5.0)
    for a, b in zip(before.fingers, after.fingers, strict=True):
        # a P servo holding its present angle droops by load / gain
        assert b.motor_angle_rad == pytest.approx(a.motor_angle_rad, abs=0.08)
    hand.apply(_cmd(mode=HandMode.SAFE))
    assert hand.read(6.0).fingers[0].motor_angle_rad == pytest.approx(
        after.fingers[0].motor_angle_rad, abs=0.08)


def test_force_mode_pulls_the_tendon() -> None:
    hand = SimHand(_no_object())
    hand.apply(_cmd(mode=HandMode.FORCE, force=(60.0, 0.0, 30.0)))
    r = hand.read(10.0)
    assert r.fingers[0].proximal_rad > 0.05  # slow: the motor's friction (report Fig. 4.15)
    assert r.fingers[1].proximal_rad == 0.0
    assert r.fingers[0].load_units == pytest.approx(60.0)


def test_readings_are_deterministic_with_a_seed() -> None:
    def run(seed: int) -> tuple:
        hand = SimHand(replace(CFG.hand, sim=replace(CFG.hand.sim, noise=True)), seed=seed)
        hand.apply(_cmd(sp=(1.4, 1.4, 1.4)))
        return tuple(hand.read(k / 40.0) for k in range(1, 41))

    assert run(1) == run(1)
    assert run(1) != run(2)


def test_velocity_mode_moves_at_the_driver_speed() -> None:
    hand = SimHand(_no_object())
    hand.apply(_cmd(sp=(2.0, 2.0, 2.0), mode=HandMode.VELOCITY))
    mid = hand.read(0.3).fingers[0].motor_angle_rad
    assert mid < 3.5 * 0.3 + 0.05  # limited by the 3.5 rad/s move speed
    assert hand.read(3.0).fingers[0].motor_angle_rad == pytest.approx(2.0, abs=0.06)


def test_preshape_swivels_fingers_1_and_2_oppositely() -> None:
    from sim.finger import ContactObject
    from sim.hand import default_hand_params, hand_outputs, initial_hand_state, preshape_step

    hp = default_hand_params()
    st = initial_hand_state(hp)
    ang, vel = 0.0, 0.0
    for _ in range(3000):
        ang, vel = preshape_step(ang, vel, 2.5, hp, 1e-3)  # beyond travel: clamped to 1.75
    assert ang == pytest.approx(1.75, abs=0.01)
    out = hand_outputs(replace(st, preshape_rad=0.5), hp, ContactObject(), EffectSet())
    assert out.swivel_rad == (0.5, -0.5, 0.0)
