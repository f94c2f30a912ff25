"""A guard for a contact the tactile cells do not see: a stalled finger with silent cells.

The environment-port layer charges the work the pads do on the object from the cells' force
estimate, and the yielding-contact guard (:mod:`teleop.control.yield_guard`) reads the shape of
that force.  Both go blind when the cells read nothing at all: dead or unplugged cells, or a
contact outside the pads (the back or side of a link, a fingertip against the palm or another
finger).  Then the servo can push into the object without the tank paying anything.

What reveals such a contact without the cells is the finger's own kinematics.  The ReFlex
finger closes in two phases: first the distal link curls ahead of the proximal one (its spring
is the softer), then both turn together, the proximal encoder following the motor (joint side)
at about its full rate.  Against an object the proximal link stops while the motor winds on:
the tendon's further travel goes into the distal bend and the tendon's stretch.  This guard
follows, per finger, chords of proximal advance against motor advance over windows of
``stall_window_rad`` of inward motor travel, and flags the finger when

* the proximal link advanced less than ``stall_ratio`` of the motor over the chord,
* the distal link is bent further than it bends in free motion (``free_curl_rad``, the motor
  ahead of the proximal encoder; beyond the first phase), and
* the cells saw no force on that finger during the chord.

A flagged finger is charged like a yielding one: each inward motor motion ``dx`` at
``tau_max dx`` (:func:`teleop.control.yield_guard.yield_charge_j`), the servo's most work
through the tendon whatever the object; the flag holds until the motor has backed out of the
stall by a window.  On a hand with working cells every stall against an object is seen by them,
so the guard never fires; with silent cells the tank empties at the servo's worst case and the
reservation freezes the set-point (the safe state), and the hand reports the finger.

The chord in which the stall is found was charged by the cells, i.e. not at all: when the
flag is raised the tank pays for it too, ``tau_max`` times the motor's inward motion over that
chord before the flagging sample (:func:`stall_recharge_j`, outside the one-sample cap, as the
yield guard's flag re-charge is; about a window of motor travel).

What it cannot see: a contact that stops the distal link alone while the proximal keeps turning
(the motor's travel then goes on into the proximal link); and energy the loop handed out on
the strength of the silent cells before the flag.  Stated in docs/controllers.md.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class StallTrack:
    """One finger's chord of proximal against motor advance."""

    anchor_motor_rad: float | None = None  # motor angle (joint side) where the chord began
    anchor_proximal_rad: float = 0.0  # proximal encoder angle there
    seen: bool = False  # the cells saw a force on the finger during the chord
    stalled: bool = False  # latched until the motor backs out of the stall by a window
    stall_motor_rad: float = 0.0  # motor angle where the stall was flagged
    wound_rad: float = 0.0  # the motor's inward motion over the chord so far


FREE = StallTrack()


def step_stall(prev: StallTrack, motor_rad: float, proximal_rad: float, force_n: float,
               window_rad: float, ratio: float, free_curl_rad: float,
               motor_prev_rad: float | None = None) -> StallTrack:
    """One hand sample of one finger: ``motor_rad`` its motor angle (joint side) at its end
    and ``motor_prev_rad`` at its start (None: not known, no winding counted),
    ``proximal_rad`` its proximal encoder, ``force_n`` the cells' total pad force estimate
    (0: none seen).  ``window_rad`` 0 turns the guard off.  The chord's winding (the motor's
    inward motion since its anchor) is what :func:`stall_recharge_j` charges when the flag
    is raised."""
    if window_rad <= 0.0:
        return FREE
    seen = force_n > 0.0
    stalled = prev.stalled
    if stalled and motor_rad < prev.stall_motor_rad - window_rad:
        stalled = False  # backed out of the stall: the finger is free again
    a = prev.anchor_motor_rad
    if a is None or motor_rad < a:
        # first sample, or the motor let go: the next chord starts from here
        return StallTrack(motor_rad, proximal_rad, seen, stalled, prev.stall_motor_rad)
    span = motor_rad - a
    wound = prev.wound_rad + (max(motor_rad - motor_prev_rad, 0.0)
                              if motor_prev_rad is not None else 0.0)
    if span < window_rad:
        if stalled == prev.stalled and (prev.seen or not seen) and wound == prev.wound_rad:
            return prev  # nothing changed within the chord
        return StallTrack(a, prev.anchor_proximal_rad, prev.seen or seen, stalled,
                          prev.stall_motor_rad, wound)
    flat = (proximal_rad - prev.anchor_proximal_rad) < ratio * span
    curled = motor_rad - proximal_rad > free_curl_rad
    if flat and curled and not (prev.seen or seen) and not stalled:
        return StallTrack(motor_rad, proximal_rad, False, True, motor_rad)
    return StallTrack(motor_rad, proximal_rad, False, stalled, prev.stall_motor_rad)


def stall_recharge_j(before: tuple[StallTrack, ...], after: tuple[StallTrack, ...],
                     torque_max_nm: float) -> float:
    """What the tank pays when a finger's stall flag is raised: ``tau_max`` times the
    motor's inward motion over the chord that found it, before this sample (this sample's
    is :func:`teleop.control.yield_guard.yield_charge_j`'s), the servo's most work through
    the tendon while the silent cells charged nothing."""
    return sum(torque_max_nm * b.wound_rad for b, a in zip(before, after, strict=False)
               if a.stalled and not b.stalled)


__all__ = ["FREE", "StallTrack", "stall_recharge_j", "step_stall"]
