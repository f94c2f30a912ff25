"""A cross-check of the tactile cells' gain against the servo's own load reading.

The environment-port layer (:mod:`teleop.control.object_port`) charges the hand's tank for the
work the pads do on the object, estimated from the cells.  Its bound assumes the cells read
within ``force_margin`` ``m`` of their calibration.  Cells that read ``g < 1/m`` of the true
force make the tank pay ``m g`` of the work; the yield guard catches that on a contact whose
force stops rising, but not on one that keeps hardening (the docs' hardening skin).  This guard
checks the gain itself, against a measurement that does not go through the cells.

*The moment about the base axle.*  The tendon pulls the finger closed with ``T r_b`` about the
base axle (``r_b``: the tendon's moment arm there); the base spring holds it open with
``k_b (t_p + t_0)`` (preloaded against the open stop: ``t_0``); the object pushes back on the
pads.  The flexure's torque acts between the two links and cancels in this balance.  While the
finger stands still and off its stop the contact moment is therefore

    tau_servo = c_L load - k_b (t_p + t_0)       (c_L: joint torque per unit of present load)

and the cells see it as ``tau_cells = F_p r_p + F_d (L cos t_d + r_d)`` (the same lever arms
the tank's work estimate uses).  The servo's load reads its effort, not the tendon's tension:
its own friction adds to it while the motor creeps inward and subtracts while it backs out
(Coulomb plus a viscous part up to ``c_v`` per rad/s of motor speed, joint side).  Over a
window of ``window_s`` in which the motor and the proximal encoder stay within ``still_rad``
(motor speed ``v``, means of both moments), the contact moment lies within

    tau_servo - c_v max(v, 0) - tol  <=  tau  <=  tau_servo + c_v max(-v, 0) + tol

with ``tol`` the stated tolerance (Coulomb friction, load resolution and noise, the spring's
and the lever arms' model error).  A window whose *lower* bound exceeds ``m tau_cells`` says
the cells read lower than their margin allows; ``LOW_WINDOWS`` such windows in a row flag the
finger (an alarm, latched: a gain error is the sensor's, not the contact's).

*Safe accounting once flagged.* The finger's cells are scaled up by ``s``, the largest ratio of
the upper bound to ``tau_cells`` over its held windows since the flag (windows whose lower
bound is at least ``tol``: with a smaller one the ratio measures the tolerance, not a gain):
every joule the cells report it put into the object is charged ``s`` times (what they report it
got back is credited as read, the conservative side), and the work it did before the flag is
charged again at ``s - 1`` (every raise of ``s`` re-charges the finger's estimated work so far
by the rise, through the margin like the work itself). The tank then pays ``m s g`` of the
work, more than all of it when ``s >= 1 / g``, which the window's upper bound gives for a gain
error common to the finger's cells: its moment and its work are estimated from the same forces
and lever arms.
Chosen over charging ``tau_max`` per radian (the yield guard's answer)
because a miscalibrated sensor stays miscalibrated: the hand keeps working, every grasp paid
at the measured ratio, where ``tau_max`` would empty the 20 J tank in a few grasps.

*A set found when a contact ends* (the yield guard's set check,
:func:`teleop.control.yield_guard.took_a_set`).  Along each contact the track keeps the cells'
work into the object and the largest ``upper / tau_cells`` of the contact's resolved windows,
``r``, whether or not they read low.  Each is a bound on the gain (``1/g <= r``), so the
object took at most ``r`` times the cells' work while the tank paid ``m`` times it: a set on a
finger with ``r`` is charged ``(r - m)`` of the contact's cells' work (:func:`set_charge_j`;
nothing when ``r <= m``), instead of the servo's torque over the contact's whole winding,
the yield guard's charge for a contact no window measured.  True cells under a firm grasp
measure ``r`` near 1.1 and a dent costs them next to nothing; at the worst case, the hard
operator's first grasp of the crushable cylinder cost one finger's set ~6 J, and the tank did
not recover under the later grasps (docs/controllers.md).  The contact's figures end when
its cells stop reading.

What it cannot see: a grasp that never stands still for a window (the check needs one: a
contact that keeps crushing at speed is the yield guard's), a contact moment smaller than about
``tol / (1 - m g)`` (a light touch), and cells reading low on the distal pad alone while the
proximal one reads true (the two share one moment).  It assumes the load reading's scale
``c_L`` and the base spring (``k_b``, ``t_0``) are calibrated, and no contact but the pads'
(a contact off the pads raises it too: the cells then read less than the servo implies).
Stated in docs/controllers.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from teleop.control.object_port import PadTrack, TactileModel
from teleop.messages import FingerState

#: held windows in a row reading low that flag a finger
LOW_WINDOWS = 2
#: the proximal joint must be this far off its open stop (the stop's reaction is unknown)
OFF_STOP_RAD = 0.02


@dataclass(frozen=True, slots=True)
class GainTrack:
    """One finger's held window and verdict."""

    anchor_motor_rad: float = math.nan  # motor angle (joint side) where the window began
    anchor_proximal_rad: float = 0.0  # proximal encoder angle there
    held_s: float = 0.0  # how long the window has been held
    samples: int = 0  # samples summed into the window
    servo_nm: float = 0.0  # sum of the servo-implied contact moments
    cells_nm: float = 0.0  # sum of the cells' contact moments
    low_windows: int = 0  # windows in a row reading low
    scale: float = 1.0  # the cells' charges are multiplied by this (> 1: flagged, latched)
    into_j: float = 0.0  # the cells' estimated work into the object so far (before the scale)
    contact_into_j: float = 0.0  # ... over the contact under way (before the scale)
    contact_ratio: float = 0.0  # the largest upper bound / cells' moment of its resolved windows

    @property
    def low(self) -> bool:
        """The finger's cells were found reading lower than their margin allows."""
        return self.scale > 1.0


UNCHECKED = GainTrack()


def cells_moment_nm(pad: PadTrack, proximal_length_m: float) -> float:
    """The cells' contact moment about the base axle: each pad's force times the lever arm
    the work estimate uses (``r_p``; ``L cos t_d + r_d``)."""
    lever = proximal_length_m * math.cos(pad.distal_rad) + pad.dist_x_m
    return pad.prox_force_n * pad.prox_x_m + pad.dist_force_n * lever


def servo_moment_nm(load_units: float, proximal_rad: float, model: TactileModel) -> float:
    """The contact moment the servo's load implies on a finger standing still: the tendon's
    moment about the base axle less the base spring's."""
    spring = model.base_spring_nm_per_rad * (proximal_rad + model.base_preload_rad)
    return model.load_torque_nm_per_unit * load_units - spring


def set_charge_j(track: GainTrack, into_j: float, margin: float) -> float | None:
    """What a set found when a contact ends (:func:`teleop.control.yield_guard.took_a_set`)
    costs a finger whose cells a resolved window of that contact measured: ``track`` its
    gain track of the contact's last sample in it, ``into_j`` the cells' work into the object
    over the sample that ended it.  Each resolved window bounds the cells' gain from below,
    ``g >= tau_c / upper``; the largest of the contact's ratios ``r`` is the safe one.  The
    object took at most ``r`` times what the cells estimate it was given; the tank paid ``m``
    times that (while the net is positive), so it is short at most ``(r - m)`` of the cells'
    work into the object over the contact, the set's plastic work included; nothing when
    ``r <= m``.  ``None`` when no window measured the cells: only the servo's worst case
    (the yield guard's flag) bounds that contact."""
    if track.contact_ratio <= 0.0:
        return None
    return max(track.contact_ratio - margin, 0.0) * (track.contact_into_j + into_j)


def reads_low(lower_nm: float, cells_nm: float, margin: float) -> bool:
    """A window's verdict: the least contact moment the servo's load allows, ``lower_nm``,
    exceeds the most the cells' ``cells_nm`` can stand for within their gain ``margin``."""
    return lower_nm > margin * cells_nm


def step_gain(prev: GainTrack, f: FingerState, cells_nm: float, into_j: float, dt_s: float,
              model: TactileModel) -> tuple[GainTrack, float]:
    """One hand sample of one finger: ``f`` its measured state, ``cells_nm`` the cells'
    contact moment (:func:`cells_moment_nm`), ``into_j`` the cells' estimated work into the
    object over the sample.  Returns the new track and what the tank pays on top of the
    sample's own charge: the finger's earlier work re-charged by a rise of the scale.
    ``gain_check_window_s`` 0 turns the check off."""
    window = model.gain_check_window_s
    if window <= 0.0:
        return prev, 0.0
    into = prev.into_j + into_j
    motor, proximal, load = f.motor_angle_rad, f.proximal_rad, f.load_units
    valid = (cells_nm > 0.0 and proximal > OFF_STOP_RAD
             and math.isfinite(motor) and math.isfinite(proximal) and math.isfinite(load))
    if cells_nm <= 0.0:  # no contact seen: no window, and the contact's figures end
        return GainTrack(scale=prev.scale, into_j=into), 0.0
    c_into, ratio = prev.contact_into_j + into_j, prev.contact_ratio
    if not valid:  # on the stop or a missing reading: no window (the contact's figures go on)
        return GainTrack(scale=prev.scale, into_j=into, contact_into_j=c_into,
                         contact_ratio=ratio), 0.0
    servo = servo_moment_nm(load, proximal, model)
    still = model.gain_check_still_rad
    if (math.isnan(prev.anchor_motor_rad) or abs(motor - prev.anchor_motor_rad) > still
            or abs(proximal - prev.anchor_proximal_rad) > still):
        # a first sample in contact, or the finger moved: a new window starts here (and the
        # windows in a row start again: the check wants a grasp held throughout)
        return GainTrack(motor, proximal, 0.0, 1, servo, cells_nm, 0, prev.scale, into,
                         c_into, ratio), 0.0
    n = prev.samples + 1
    held = prev.held_s + dt_s
    s_sum, c_sum = prev.servo_nm + servo, prev.cells_nm + cells_nm
    if held < window - 1e-9:  # (a sum of sample periods: not exactly the window)
        return GainTrack(prev.anchor_motor_rad, prev.anchor_proximal_rad, held, n, s_sum,
                         c_sum, prev.low_windows, prev.scale, into, c_into, ratio), 0.0
    tau_s, tau_c = s_sum / n, c_sum / n
    v = (motor - prev.anchor_motor_rad) / held
    c_v, tol = model.gain_check_damping_nm_s_per_rad, model.gain_check_tolerance_nm
    lower = tau_s - c_v * max(v, 0.0) - tol
    upper = tau_s + c_v * max(-v, 0.0) + tol
    low = prev.low_windows + 1 if reads_low(lower, tau_c, model.force_margin) else 0
    scale = prev.scale
    # only a window whose servo moment is resolved (its lower bound at least the tolerance,
    # so ``upper`` is within 3x of it) raises the scale: otherwise ``upper / tau_c`` measures
    # the tolerance, not a gain (a flagged finger opening, servo and cells at 0.02 N m, read
    # as 8x and more, and every raise re-charges all its work so far: -404 J on a live run)
    if (scale > 1.0 or low >= LOW_WINDOWS) and lower >= tol:
        scale = max(scale, upper / tau_c)
    recharge = (scale - prev.scale) * prev.into_j
    if lower >= tol:  # a resolved window: its bound on the gain, for a set found later
        ratio = max(ratio, upper / tau_c)
    nxt = GainTrack(motor, proximal, 0.0, 1, servo, cells_nm, low, scale, into, c_into,
                    ratio)
    return nxt, recharge


def check_gains(model: TactileModel, prev: tuple[GainTrack, ...], pads: tuple[PadTrack, ...],
                fingers: tuple[FingerState, ...], works: tuple[tuple[float, float], ...],
                dt_s: float) -> tuple[tuple[GainTrack, ...], tuple[tuple[float, float], ...],
                                      float]:
    """The check for every finger: ``(tracks, works with a flagged finger's work into the
    object scaled, re-charge J)``; ``works`` comes back as given while no finger is
    flagged."""
    tracks, recharge = [], 0.0
    for g, pad, f, (into, _) in zip(prev, pads, fingers, works, strict=False):
        t, r = step_gain(g, f, cells_moment_nm(pad, model.proximal_length_m), into, dt_s,
                         model)
        tracks.append(t)
        recharge += r
    if all(t.scale == 1.0 for t in tracks):
        return tuple(tracks), works, recharge
    scaled = tuple((o * t.scale, i) for (o, i), t in zip(works, tracks, strict=False))
    return tuple(tracks), scaled + works[len(scaled):], recharge


__all__ = ["LOW_WINDOWS", "OFF_STOP_RAD", "UNCHECKED", "GainTrack", "cells_moment_nm",
           "check_gains", "reads_low", "set_charge_j", "servo_moment_nm", "step_gain"]
