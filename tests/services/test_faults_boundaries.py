"""Boundary checks the fault suite relies on: sender epochs on the in-process bus, the
energy-total check (decrease, jump, outage re-baseline), and joint-limit clamping at the hand
service.  Each test also shows the check is load-bearing: without it the bad value gets
through."""

from __future__ import annotations

import numpy as np
import pytest

from services.hand_service import HandService, clamp_command
from teleop.config import load_config
from teleop.control.energy_channel import TotalReceiver, receive_total
from teleop.messages import HandCommand, HandMode, Header
from teleop.transport.clock import VirtualClock
from teleop.transport.codec import encode
from teleop.transport.inproc_bus import InProcessHub
from tests.services._svc_fakes import FakeHand


def _cmd(seq: int, energy_j: float, sp: float = 1.0) -> HandCommand:
    return HandCommand(Header(seq=seq, t_s=0.0, energy_total_j=energy_j), (sp,) * 3, 0.0,
                       HandMode.POSITION)


def _hub(jump_max_j: float = 10.0) -> tuple[VirtualClock, InProcessHub]:
    cfg = load_config(None, [])
    clock = VirtualClock(0.0)
    return clock, InProcessHub(cfg.links, clock, energy_jump_max_j=jump_max_j)


def _totals(view, signal: str = "hand_command") -> list[float]:  # noqa: ANN001
    return [r.message.header.energy_total_j for r in view.receive(signal)]


def test_a_restarted_sender_is_heard_and_its_energy_continues_monotone() -> None:
    clock, hub = _hub()
    hand = hub.bus("hand")
    ctrl = hub.bus("controller")
    for k in range(1, 6):
        ctrl.publish("hand_command", _cmd(k, 1.0 * k))
    assert _totals(hand) == [1.0, 2.0, 3.0, 4.0, 5.0]
    ctrl.publish("hand_command", _cmd(6, 6.0))  # in flight when the controller dies
    ctrl.close()
    ctrl2 = hub.bus("controller")  # restarted: counts seq and energy from the start again
    for k in range(1, 4):
        ctrl2.publish("hand_command", _cmd(k, 0.5 * k))
    got = _totals(hand)
    # the old incarnation's message in flight is gone, the new one's are not stale, and the
    # totals handed on continue from 5 J: the control layer credits exactly the new sends
    assert got == [5.5, 6.0, 6.5]
    rx, credited = TotalReceiver(), 0.0
    for e in [1.0, 2.0, 3.0, 4.0, 5.0, *got]:
        rx, inc = receive_total(rx, e)
        credited += inc
    assert credited == pytest.approx(5.0 + 1.5)
    assert hand.stats().rejects.count("stale_seq") == 0


def test_a_receiver_joining_a_running_sender_credits_nothing_of_the_past() -> None:
    clock, hub = _hub()
    hand = hub.bus("hand")
    ctrl = hub.bus("controller")
    ctrl.publish("hand_command", _cmd(500, 8.0))  # seq 500: not the sender's first message
    ctrl.publish("hand_command", _cmd(501, 8.2))
    assert _totals(hand) == pytest.approx([0.0, 0.2])


def test_energy_decrease_and_jump_are_rejected_per_reason() -> None:
    clock, hub = _hub(jump_max_j=10.0)
    hand = hub.bus("hand")
    hub.bus("controller")
    for payload in (encode(_cmd(1, 1.0)), encode(_cmd(2, 0.5)), encode(_cmd(3, 500.0)),
                    encode(_cmd(4, 2.0))):
        hand.inject("hand_command", payload)
    assert _totals(hand) == [1.0, 2.0]
    rej = hand.stats().rejects
    assert rej.count("energy_decrease") == 1 and rej.count("energy_jump") == 1


def test_without_the_jump_check_an_injected_jump_would_be_credited() -> None:
    """The check is load-bearing: with the cap off the forged total is credited in full."""
    credited = {}
    for cap in (10.0, float("inf")):
        clock, hub = _hub(jump_max_j=cap)
        hand = hub.bus("hand")
        hub.bus("controller")
        rx = TotalReceiver()
        total = 0.0
        for seq, e in ((1, 1.0), (2, 1001.0), (3, 1.5)):  # genuine, forged, genuine
            hand.inject("hand_command", encode(_cmd(seq, e)))
            for r in hand.receive("hand_command"):
                rx, inc = receive_total(rx, r.message.header.energy_total_j)
                total += inc
        credited[cap] = total
    assert credited[float("inf")] == pytest.approx(1001.0)  # the forged 1000 J got through
    assert credited[10.0] == pytest.approx(1.5)  # forged one rejected, genuine ones credited


def test_a_single_forged_jump_cannot_rebaseline_but_an_outage_does() -> None:
    clock, hub = _hub(jump_max_j=10.0)
    hand = hub.bus("hand")
    hub.bus("controller")
    hand.inject("hand_command", encode(_cmd(1, 1.0)))
    hand.inject("hand_command", encode(_cmd(2**40, 1e9)))  # forged: rejected
    hand.inject("hand_command", encode(_cmd(2, 1.1)))  # genuine: accepted, clears the run
    assert _totals(hand) == pytest.approx([1.0, 1.1])
    # a run of forged jumps with a seq far ahead never re-baselines (nor shuts out the sender)
    for k in range(5):
        hand.inject("hand_command", encode(_cmd(2**40 + k, 1e9)))
    hand.inject("hand_command", encode(_cmd(3, 1.1)))  # same total: credits nothing more
    assert _totals(hand) == pytest.approx([1.1])
    # a live sender back from a cut link: its total grew 30 J while nothing got through
    for k, e in enumerate((31.0, 31.1, 31.2, 31.3), start=100):
        hand.inject("hand_command", encode(_cmd(k, e)))
    # two rejected as jumps, the third re-baselines crediting nothing, then it continues
    assert _totals(hand) == pytest.approx([1.1, 1.2])
    assert hand.stats().rejects.count("energy_jump") == 1 + 5 + 2
    assert hand.stats().rejects.count("stale_seq") == 0


def test_clamp_command_limits_to_the_joint_travel() -> None:
    cmd = _cmd(1, 0.0, sp=5.0)
    out = clamp_command(cmd, 3.6, 1.75)
    assert out.finger_setpoint_rad == (3.6, 3.6, 3.6)
    inside = _cmd(1, 0.0, sp=1.0)
    assert clamp_command(inside, 3.6, 1.75) is inside
    neg = HandCommand(Header(1, 0.0, 0.0), (-0.5, 1.0, 2.0), 9.0, HandMode.POSITION)
    assert clamp_command(neg, 3.6, 1.75).finger_setpoint_rad == (0.0, 1.0, 2.0)
    assert clamp_command(neg, 3.6, 1.75).preshape_rad == 1.75


def _drive_hand(setpoint_rad: float, ticks: int = 200) -> tuple[FakeHand, HandService]:
    """A hand service fed a command beyond the joint travel (valid on the wire: the codec
    allows up to 2 pi) by a controller view; returns the backend fake and the service."""
    cfg = load_config(None, ["hand.dynamixel.finger_travel_rad=1.0"])
    clock = VirtualClock(0.0)
    hub = InProcessHub.from_config(cfg, clock)
    fake = FakeHand(contact_rad=10.0)  # nothing to grasp: the fingers go where told
    svc = HandService(cfg, hub.bus("hand"), fake)
    ctrl = hub.bus("controller")
    svc.start()
    for k in range(ticks):
        t = k / cfg.hand.state_rate_hz
        clock.set(t)
        ctrl.publish("hand_command", HandCommand(Header(k + 1, t, 0.01 * k),
                                                 (setpoint_rad,) * 3, 0.0, HandMode.POSITION))
        svc.tick(t)
    return fake, svc


def test_nothing_beyond_the_joint_limits_reaches_the_backend(
        monkeypatch: pytest.MonkeyPatch) -> None:
    fake, svc = _drive_hand(2.5)
    applied = np.array([c.finger_setpoint_rad for c in fake.applied])
    assert applied.max() <= 1.0 + 1e-12
    assert applied.max() > 0.9  # it did go to the limit
    assert svc.clamp_count > 0
    # without the clamp the same command drives the fake past its travel
    monkeypatch.setattr("services.hand_service.clamp_command", lambda cmd, *a: cmd)
    fake2, _ = _drive_hand(2.5)
    assert max(max(c.finger_setpoint_rad) for c in fake2.applied) > 1.0 + 0.1
