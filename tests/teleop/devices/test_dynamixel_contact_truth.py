"""The dynamixel backend's load-based contact flags against the emulated finger's own contact.

The direct-USB layout has no tactile cells, so the hand's passivity layer (``hand_port =
servo``) learns of an object only from the flags :class:`DynamixelHand` estimates from the
motor load.  A finger flagged free gets the free-motion refund: the servo's work on it is
taken to stay inside the hand.  Whatever the pads push into the object while the flag is off
went somewhere the layer did not charge for.  These tests measure that work with the physical
audit of the emulated finger (:mod:`sim.audit`), not with the controller's books: the gross
work pushed into the object over the samples a touching finger spent flagged free, an upper
bound of the refund's error (the object gives part of it back on release).  It says how good
the flags are, not that the whole loop is active: the layer charges every flagged advance at
the servo's torque limit, far more than the object takes.
"""

from __future__ import annotations

import time
from bisect import bisect_right
from collections.abc import Callable
from itertools import pairwise
from pathlib import Path

import pytest

from sim.params import default_finger_params
from sim.servo_emulator_physics import FingerServoPhysics
from sim.servo_emulator_pty import PtyServoEmulator, make_bus_emulator
from teleop.config.hand import DynamixelConfig, ObjectConfig
from teleop.devices.dynamixel_hand import build_dynamixel_hand
from teleop.messages import HandCommand, Header
from teleop.recording import read_recording
from tests.teleop.devices.test_dynamixel_hand import HOMES, config

#: object work (J, all fingers, both closes) a sound estimate would leave unflagged
UNPAID_J_MAX = 0.002


SETPOINTS = Path(__file__).parent / "data" / "dynamixel_setpoints.csv"
PERIOD_S = 0.025  # the hand's state period (hand.state_rate_hz = 40)
Goal = float | tuple[float, float, float] | None  # a set-point for all fingers, or each's
Sample = tuple[list[float], list[bool], tuple[bool, ...], list[float]]  # x, flags, touch, work


def ramp_profile(ramp_rad_s: float) -> Callable[[float], Goal]:
    """Close (set-point ramped at ``ramp_rad_s`` to 3 rad, 3 s), open (2 s), close again;
    ``None`` when done."""
    def goal(t_s: float) -> Goal:
        if t_s < 3.0:
            return min(3.0, ramp_rad_s * t_s)
        if t_s < 5.0:
            return 0.0
        return min(3.0, ramp_rad_s * (t_s - 5.0)) if t_s < 8.0 else None
    return goal


def recorded_profile() -> Callable[[float], Goal]:
    """The set-points of four grasps as the two-layer hand sent them in a ``teleop up`` run
    (40 Hz rows, held between them); ``None`` after the last row."""
    rec = read_recording(SETPOINTS)
    t = rec.t_s.tolist()
    y = list(zip(*(rec.column(f"setpoint_rad_f{k}").tolist() for k in (1, 2, 3)), strict=True))

    def goal(t_s: float) -> Goal:
        if t_s > t[-1]:
            return None
        return y[max(bisect_right(t, t_s) - 1, 0)]
    return goal


def account(prev: Sample, now: Sample) -> tuple[float, float]:
    """Over one sample, per finger free (flag off) at both ends, as the layer's refund is:
    the work the pads pushed into the object (gross: each sample's increase; an upper bound
    of what the refund credited as staying in the hand while it went into the object, since
    the object may give some back later) and the motor travel while the finger touched."""
    unpaid = hidden = 0.0
    for k in range(3):
        if not (now[1][k] or prev[1][k]):
            unpaid += max(now[3][k] - prev[3][k], 0.0)
            if now[2][k] or prev[2][k]:
                hidden += max(now[0][k] - prev[0][k], 0.0)
    return unpaid, hidden


def measure(profile: Callable[[float], Goal], *, kind: str = "cylinder",
            seen: Callable[[float, Sample, list[float]], None] | None = None,
            **cfg: object) -> tuple[float, float, float]:
    """Drive the hand on the emulator's object (``kind``: its default cylinder, or ``none``)
    through ``profile`` (set-point per elapsed time) at the hand's 40 Hz, read then apply as
    the hand service does; ``seen(t_s, sample, loads)`` gets every sample with the fingers'
    present loads.  Returns (object work done while a finger's flag was off, net object work,
    motor travel in true contact with the flag off), all fingers."""
    emu = PtyServoEmulator(make_bus_emulator(1, homes_counts=list(HOMES),
                                             object_cfg=ObjectConfig(kind=kind)))
    emu.start()
    hand = build_dynamixel_hand(config(emu, **cfg))
    physics = emu.bus.physics
    assert isinstance(physics, FingerServoPhysics)  # the finger model, not the fallback
    unpaid = hidden_rad = 0.0
    try:
        hand.start()
        with emu.lock:
            physics.audit_on = True
        prev: Sample | None = None
        t0 = time.monotonic()
        tick = 0
        while (goal := profile(el := time.monotonic() - t0)) is not None:
            reading = hand.read(el)
            with emu.lock:
                now = ([f.motor_angle_rad for f in reading.fingers],
                       [any(f.contact) for f in reading.fingers], physics.touching(),
                       list(physics.object_work_j))
            if seen is not None:
                seen(el, now, [f.load_units for f in reading.fingers])
            if prev is not None:
                u, h = account(prev, now)
                unpaid, hidden_rad = unpaid + u, hidden_rad + h
            prev = now
            y = goal if isinstance(goal, tuple) else (goal, goal, goal)
            hand.apply(HandCommand(Header(1, 0.0, 0.0), y, 0.0))
            tick += 1
            time.sleep(max(t0 + tick * PERIOD_S - time.monotonic(), 0.0))
        with emu.lock:
            total = sum(physics.object_work_j)
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
                   "the flag comes late (measured: 2.1-4.1 rad of motor travel in contact "
                   "unflagged, 0.028-0.073 J of the pads' work on the object; README, hardware "
                   "section)")
def test_a_slow_close_is_flagged_before_the_pads_work_on_the_object() -> None:
    unpaid, _, hidden = measure(ramp_profile(0.5))
    assert unpaid <= UNPAID_J_MAX, (unpaid, hidden)


Replay = tuple[float, float, float, list[tuple[float, Sample, list[float]]]]


@pytest.fixture(scope="module")
def replay() -> Replay:
    """The four recorded grasps' set-points on the cylinder once: the measure's three figures
    and every sample (time, sample, loads)."""
    rows: list[tuple[float, Sample, list[float]]] = []
    unpaid, total, hidden = measure(recorded_profile(),
                                    seen=lambda t, now, loads: rows.append((t, now, loads)))
    return unpaid, total, hidden, rows


def test_the_set_points_of_a_live_run_leave_no_more_unpaid_than_today(replay: Replay) -> None:
    # A regression bound, not a clean bill: the estimate leaves 0.052-0.081 J of the pads'
    # work unflagged on these set-points (four runs).  A rule that ignored the stalls the
    # overload back-off made (tried 2026-11-27, not merged) left 0.26-0.35 J (three runs).
    unpaid, total, hidden, _ = replay
    assert total > 0.005  # the grasps reached the cylinder (net 0.014 J when measured)
    assert unpaid <= 0.15, (unpaid, hidden)


#: the free close's lowest load at 0.5 rad/s (units; the load characterisation below)
FREE_LOAD_MIN_UNITS = 217.0


def test_the_servo_turns_the_squeeze_into_friction_not_object_work(replay: Replay) -> None:
    """Why no load-based charge makes this backend's loop sustainable (README, hardware
    section).  From the measured loads: the motor port's work on the four grasps (load /
    ``units_per_n`` x spool radius x shaft advance, the shaft at ``finger_ratio`` times the
    joint-side motor angle), what comes back on release, and a charge that credits the motor
    friction at the free close's lowest load; against the pads' work on the cylinder from
    the emulator's own audit.  Measured 2026-11-27: 50.5 J in, 0.05 J back, the pads 0.73 J
    gross (0.014 J net), the credited charge 8.3 J: about 2 J a grasp where the trigger
    refills at most ~0.2 J a stroke.  A characterisation: should the servo's friction change,
    this fails and the README's budget is stale."""
    _, _, _, rows = replay
    fp = default_finger_params()
    ratio = DynamixelConfig().finger_ratio
    j_per_unit_rad = fp.r_motor_m / fp.units_per_n  # J per load unit per shaft radian
    work_in = work_back = credited = pads = 0.0
    for (_, a, la), (_, b, lb) in pairwise(rows):
        for k in range(3):
            shaft = (b[0][k] - a[0][k]) * ratio
            w = 0.5 * (la[k] + lb[k]) * j_per_unit_rad * shaft
            work_in, work_back = work_in + max(w, 0.0), work_back + max(-w, 0.0)
            credited += max(lb[k] - FREE_LOAD_MIN_UNITS, 0.0) * j_per_unit_rad * max(shaft, 0.0)
            pads += max(b[3][k] - a[3][k], 0.0)
    print(f"motor port: {work_in:.2f} J in, {work_back:.3f} J back; pads' gross work on the "
          f"cylinder {pads:.3f} J; friction-credited load charge {credited:.2f} J")
    assert work_in > 20.0 * pads  # the motor's work goes into its friction
    assert work_back < 0.05 * work_in  # and does not come back on release
    assert credited / 4 > 5 * 0.2  # credited, still five trigger strokes' refill a grasp


def _closing_loads(kind: str) -> tuple[list[float], list[float]]:
    """The present loads (units) of every finger over a 0.5 rad/s close (3 s, from 0.5 s on),
    on the samples it moved closed faster than 0.1 rad/s since the last: (those touching
    nothing, those touching the object as the emulated finger's own contact says)."""
    free: list[float] = []
    touching: list[float] = []
    last: list[tuple[float, Sample]] = []

    def seen(t_s: float, now: Sample, loads: list[float]) -> None:
        if last:
            t0, before = last[0]
            for k in range(3):
                if (now[0][k] - before[0][k]) / (t_s - t0) > 0.1 and t_s > 0.5:
                    (touching if now[2][k] else free).append(loads[k])
        last[:] = [(t_s, now)]

    measure(lambda t_s: min(3.0, 0.5 * t_s) if t_s < 3.0 else None, kind=kind, seen=seen)
    return free, touching


def test_the_load_cannot_tell_a_creep_into_the_cylinder_from_a_free_close() -> None:
    """Why the flags need a stall (README, hardware section): the emulated finger's motor
    friction loads a free close about as much as the cylinder loads a finger creeping into it
    (measured 2026-11-27, two runs: free 217-341 units, creeping 170-516, 61-62 % of those
    within 10 units of the free range), so no load threshold tells the two apart.  A characterisation of
    the emulator's physics, not a wish: should this fail, the README's reason for the late
    flags is stale (a tenth of the motor's viscous friction fails it: free 70-93, 16 %)."""
    free, _ = _closing_loads("none")
    _, creeping = _closing_loads("cylinder")
    assert len(free) >= 20 and len(creeping) >= 20, (len(free), len(creeping))
    lo, hi = min(free), max(free)
    inside = sum(lo - 10.0 <= x <= hi + 10.0 for x in creeping) / len(creeping)
    print(f"free close {lo:.0f}-{hi:.0f} units ({len(free)} samples); creeping into the "
          f"cylinder {min(creeping):.0f}-{max(creeping):.0f} ({len(creeping)}), "
          f"{inside:.0%} of them within 10 units of the free range")
    assert inside >= 0.5
