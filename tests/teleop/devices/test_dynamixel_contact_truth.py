"""The dynamixel backend's load-based contact flags against the emulated finger's own contact.

The direct-USB layout has no tactile cells, so the hand's passivity layer (``hand_port =
servo``) learns of an object only from the flags :class:`DynamixelHand` estimates from the
motor load.  A finger flagged free gets the free-motion refund: the servo's work on it is
taken to stay inside the hand.  Whatever the pads push into the object while the flag is off
is energy the layer never paid for.  These tests measure that work with the physical audit
of the emulated finger (:mod:`sim.audit`), not with the controller's books.
"""

from __future__ import annotations

import time

import pytest

from sim.servo_emulator_pty import PtyServoEmulator, make_bus_emulator
from teleop.config.hand import ObjectConfig
from teleop.devices.dynamixel_hand import build_dynamixel_hand
from tests.teleop.devices.test_dynamixel_hand import HOMES, command, config

#: object work (J, all fingers, both closes) allowed while a touching finger is flagged free
UNPAID_J_MAX = 0.002


def close_twice(ramp_rad_s: float, **cfg: object) -> tuple[float, float, float]:
    """Close onto the default cylinder (set-point ramped at ``ramp_rad_s`` to 3 rad), open,
    close again, at the hand's 40 Hz.  Returns (object work while a finger's flag was off,
    total object work, motor travel in true contact with the flag off), all fingers."""
    emu = PtyServoEmulator(make_bus_emulator(1, homes_counts=list(HOMES),
                                             object_cfg=ObjectConfig(kind="cylinder")))
    emu.start()
    hand = build_dynamixel_hand(config(emu, **cfg))
    unpaid = hidden_rad = 0.0
    try:
        hand.start()
        physics = emu.bus.physics
        with emu.lock:
            physics.audit_on = True  # type: ignore[attr-defined]
        prev = None
        for target, dur in ((3.0, 3.0), (0.0, 2.0), (3.0, 3.0)):
            t0 = time.monotonic()
            start = prev[0][0] if prev else 0.0
            while (el := time.monotonic() - t0) < dur:
                goal = min(target, start + ramp_rad_s * el) if target > start else target
                hand.apply(command(goal))
                reading = hand.read(el)
                with emu.lock:
                    touch = physics.touching()  # type: ignore[attr-defined]
                    work = list(physics.object_work_j)  # type: ignore[attr-defined]
                x = [f.motor_angle_rad for f in reading.fingers]
                flag = [any(f.contact) for f in reading.fingers]
                if prev is not None:
                    for k in range(3):
                        if not (flag[k] or prev[1][k]):
                            unpaid += max(work[k] - prev[3][k], 0.0)
                            if touch[k] or prev[2][k]:
                                hidden_rad += max(x[k] - prev[0][k], 0.0)
                prev = (x, flag, touch, work)
                time.sleep(0.025)
        with emu.lock:
            total = sum(physics.object_work_j)  # type: ignore[attr-defined]
    finally:
        hand.close()
        emu.stop()
    return unpaid, total, hidden_rad


def test_a_fast_close_is_flagged_before_the_pads_work_on_the_object() -> None:
    unpaid, total, hidden = close_twice(ramp_rad_s=4.0)
    assert total > 0.03  # the fingers did squeeze the cylinder (0.08 J when measured)
    assert unpaid <= UNPAID_J_MAX, (unpaid, hidden)


def test_the_measure_sees_a_contact_the_flags_miss() -> None:
    # the estimate switched off (a contact threshold no load reaches): all the work is unpaid
    unpaid, _, hidden = close_twice(ramp_rad_s=4.0, contact_load_units=1023.0)
    assert unpaid > 25 * UNPAID_J_MAX and hidden > 1.0  # measured 0.17 J, 5.6 rad


@pytest.mark.xfail(strict=True, reason="known defect: a slow close creeps into the cylinder "
                   "faster than the 0.1 rad/s stall speed, loaded but never 'stalled', so "
                   "the flag comes late (measured: 2.1 rad of motor travel in contact unflagged, "
                   "0.029 J of the 0.047 J the pads did on the object; README, hardware "
                   "section)")
def test_a_slow_close_is_flagged_before_the_pads_work_on_the_object() -> None:
    unpaid, _, hidden = close_twice(ramp_rad_s=0.5)
    assert unpaid <= UNPAID_J_MAX, (unpaid, hidden)
