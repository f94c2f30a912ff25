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
from bisect import bisect_right
from collections.abc import Callable
from pathlib import Path

import pytest

from sim.servo_emulator_pty import PtyServoEmulator, make_bus_emulator
from teleop.config.hand import ObjectConfig
from teleop.devices.dynamixel_hand import build_dynamixel_hand
from teleop.messages import HandCommand, Header
from tests.teleop.devices.test_dynamixel_hand import HOMES, config

#: object work (J, all fingers, both closes) a sound estimate would leave unflagged
UNPAID_J_MAX = 0.002


SETPOINTS = Path(__file__).parent / "data" / "dynamixel_setpoints.csv"


def ramp_profile(ramp_rad_s: float) -> Callable[[float], float | None]:
    """Close (set-point ramped at ``ramp_rad_s`` to 3 rad, 3 s), open (2 s), close again;
    ``None`` when done."""
    def goal(t_s: float) -> float | None:
        if t_s < 3.0:
            return min(3.0, ramp_rad_s * t_s)
        if t_s < 5.0:
            return 0.0
        return min(3.0, ramp_rad_s * (t_s - 5.0)) if t_s < 8.0 else None
    return goal


def recorded_profile() -> Callable[[float], tuple[float, float, float] | None]:
    """The set-points of two grasps as the two-layer hand sent them in a ``teleop up`` run
    (40 Hz rows, held between them); ``None`` after the last row."""
    rows = [line.split(",") for line in SETPOINTS.read_text().splitlines()[3:]]
    t = [float(r[0]) for r in rows]
    y = [(float(r[1]), float(r[2]), float(r[3])) for r in rows]

    def goal(t_s: float) -> tuple[float, float, float] | None:
        if t_s > t[-1]:
            return None
        return y[max(bisect_right(t, t_s) - 1, 0)]
    return goal


def measure(profile: Callable[[float], object], **cfg: object) -> tuple[float, float, float]:
    """Drive the hand on the emulator's default cylinder through ``profile`` (set-point per
    elapsed time) at the hand's 40 Hz.  Returns (object work done while a finger's flag was
    off, net object work, motor travel in true contact with the flag off), all fingers."""
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
        t0 = time.monotonic()
        while (goal := profile(el := time.monotonic() - t0)) is not None:
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
            y = goal if isinstance(goal, tuple) else (goal,) * 3
            hand.apply(HandCommand(Header(1, 0.0, 0.0), y, 0.0))  # type: ignore[arg-type]
            time.sleep(0.025)
        with emu.lock:
            total = sum(physics.object_work_j)  # type: ignore[attr-defined]
    finally:
        hand.close()
        emu.stop()
    return unpaid, total, hidden_rad


def test_the_measure_sees_a_contact_the_flags_miss() -> None:
    # the estimate switched off (a contact threshold no load reaches): all the work is unpaid
    unpaid, _, hidden = measure(ramp_profile(4.0), contact_load_units=1023.0)
    assert unpaid > 0.1 and hidden > 2.0  # measured 0.17-0.23 J, 5.6-5.8 rad


@pytest.mark.xfail(strict=True, reason="known defect: a slow close creeps into the cylinder "
                   "faster than the 0.1 rad/s stall speed, loaded but never 'stalled', so "
                   "the flag comes late (measured: 2.1-3.8 rad of motor travel in contact "
                   "unflagged, 0.028-0.069 J of the pads' work on the object; README, hardware "
                   "section)")
def test_a_slow_close_is_flagged_before_the_pads_work_on_the_object() -> None:
    unpaid, _, hidden = measure(ramp_profile(0.5))
    assert unpaid <= UNPAID_J_MAX, (unpaid, hidden)


def test_the_set_points_of_a_live_run_leave_no_more_unpaid_than_today() -> None:
    # A regression bound, not a clean bill: the estimate leaves 0.055-0.081 J of the pads'
    # work unflagged on these set-points (measured twice).  A rule that ignored the stalls the
    # overload back-off made (tried 2026-11-27, not merged) left 0.27-0.35 J.
    unpaid, total, hidden = measure(recorded_profile())
    assert total > 0.005  # the grasps reached the cylinder (net 0.014 J when measured)
    assert unpaid <= 0.15, (unpaid, hidden)
