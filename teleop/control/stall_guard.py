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

What it cannot see: a contact that stops the distal link alone while the proximal keeps turning
(the motor's travel then goes on into the proximal link); and the motion of the chord in which
the stall began (at most a window) is charged by the cells, i.e. not at all.  Stated in
docs/controllers.md.
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


FREE = StallTrack()


def step_stall(prev: StallTrack, motor_rad: float, proximal_rad: float, force_n: float,
               window_rad: float, ratio: float, free_curl_rad: float) -> StallTrack:
    """One hand sample of one finger: ``motor_rad`` its motor angle (joint side),
    ``proximal_rad`` its proximal encoder, ``force_n`` the cells' total pad force estimate
    (0: none seen).  ``window_rad`` 0 turns the guard off."""
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
    if span < window_rad:
        if stalled == prev.stalled and (prev.seen or not seen):
            return prev  # nothing changed within the chord (most samples)
        return StallTrack(a, prev.anchor_proximal_rad, prev.seen or seen, stalled,
                          prev.stall_motor_rad)
    flat = (proximal_rad - prev.anchor_proximal_rad) < ratio * span
    curled = motor_rad - proximal_rad > free_curl_rad
    if flat and curled and not (prev.seen or seen) and not stalled:
        return StallTrack(motor_rad, proximal_rad, False, True, motor_rad)
    return StallTrack(motor_rad, proximal_rad, False, stalled, prev.stall_motor_rad)


__all__ = ["FREE", "StallTrack", "step_stall"]
