"""A guard that does not trust the tactile gain: yielding contacts are charged at servo torque.

The environment-port layer (:mod:`teleop.control.object_port`) charges the work the pads do on
the object from the tactile cells' force estimate.  Its bound rests on the cells' gain being
within the margin ``m`` of their calibration: cells reading ``g < 1/m`` of the true force make
the tank pay only ``m g`` of the work.  On an elastic object that under-charge is bounded and
given back with the squeeze (the object returns what it took and the estimate credits the same
fraction of it), but an object that *yields* (crushes, slides away, flows) keeps every joule:
the deficit grows with every millimetre the pads advance, without limit.

What tells a yielding contact apart does not depend on the gain: the *shape* of force against
advance.  An elastic contact pushes back harder the further the pads go in (its force rises
roughly in proportion to the advance, or faster as a core is met); a yielding one stops
rising while the pads keep advancing.  Per finger, over one contact episode (the estimated
pad force above zero), this guard follows

* the finger's pad advance ``q`` along the contact normals driven by its proximal joint (the
  encoder's angle, not the motor-based distal estimate, which grows with the tendon's stretch
  as the force rises and would read a stalled, squeezing finger as advancing), each pad's
  share weighted by its estimated force (a gain error scales the weights alike, so ``q`` is in
  metres whatever the gain), and
* chords of force against advance over windows of ``yield_window_m`` of advance: the chord
  stiffness ``(F - F_a) / (q - q_a)`` (also gain-scaled, but only its ratio to the episode's
  stiffest chord is used).

Two chords in a row below ``yield_stiffness_ratio`` of the episode's stiffest chord flag the
finger as yielding until its contact ends (a yield keeps its chords flat; noise makes one flat
chord now and then, rarely two in a row).  From then on the tank stops trusting the cells for that
finger: each inward motion ``dx`` of its motor (joint side) is charged ``tau_max dx``, the most
work the servo can do through the tendon whatever the object and the cells say, and nothing the
cells report for it is credited back.  The tank then empties at the servo's worst case, the
reservation (:func:`teleop.control.passivity_layer.reserve_project`) freezes the set-point
when it is spent, and the hand reports the finger (an alarm: the contact is crushing or
sliding and its tactile estimate is not relied on).

A contact too brief for two flat chords (a quick grasp: the pads crush the object for less
than two windows, then let go) is judged once more when it ends (``set_check``, the hand's
``yield_set_check``, on by default), by the set it left
(:func:`took_a_set`): an elastic contact unloads along the path it loaded on, so its force
runs out where the loading path began; a crushed one loses its force with the pads still
well in.  Along the contact the guard keeps the loading path (a point each time the force
passes the last by 5 %); when the force is gone, pads that stood at the contact's last
sample more than a window beyond where the path first reached that sample's force, less half
the sample's own motion (:func:`set_beyond_m`), flag the finger for that one sample
(:data:`SET_FOUND`), and the flag's re-charge pays the episode's winding (the hand charges a
finger whose cells the gain cross-check measured in the contact at the gain it measured
instead, and does not flag it: :func:`teleop.control.gain_check.set_charge_j`).  Only the last
sample is judged: while a contact lasts, the force against the estimated advance may stray
from the path in either direction (a fingertip sliding along a block's face reads several
millimetres of it), but an elastic contact's force runs out where it began.  The shape
again, not the gain: the force only picks the point on the path.

What it cannot see: physics that absorbs energy while its force keeps rising at least at
``yield_stiffness_ratio`` of its initial stiffness (a strongly work-hardening material with
cells reading low); crushing done by the distal link alone while the proximal joint stands
still; and, until the flag is raised, the advance before it, charged by the cells (``(1 -
m g)`` of its work short): two windows on a clear yield, but longer while the force keeps
creeping up.  When the flag is raised the tank pays for that advance again at the servo's
torque (:func:`flag_recharge_j`: ``tau_max`` times the motor's winding over the episode),
so the shortfall is made good from then on; energy the loop handed out *before* the flag on
the strength of it is not (cells reading a millionth in the harness: flagged ~2.5 s into
the push, after the bound broke).  All are stated in docs/controllers.md.
"""

from __future__ import annotations

import math
from bisect import bisect_left
from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class YieldTrack:
    """One finger's contact episode as the guard sees it."""

    in_contact: bool = False
    advance_m: float = 0.0  # force-weighted pad advance since the episode began
    anchor_m: float = 0.0  # advance at the start of the current chord
    anchor_n: float = 0.0  # estimated force there
    stiffest_n_per_m: float = 0.0  # stiffest chord of the episode (gain-scaled)
    anchor_motor_rad: float = 0.0  # motor angle (joint side) there
    low_chords: int = 0  # flat chords in a row
    yielding: bool = False  # latched until the contact ends
    wound_rad: float = 0.0  # the motor's inward motion (joint side) over the episode
    force_n: float = 0.0  # estimated force at the last sample
    step_m: float = 0.0  # the pads' advance over the last sample
    #: the loading path: (estimated force, advance) each time the force first passed
    #: ``LOADING_STEP`` times the last point's (the episode's first reading the first point)
    loading: tuple[tuple[float, float], ...] = ()


NO_CONTACT = YieldTrack()
#: a contact that ended having taken a set (:func:`took_a_set`): flagged for the one sample
#: in which it ended, which makes :func:`flag_recharge_j` charge the episode's winding
SET_FOUND = YieldTrack(yielding=True)

#: flat chords in a row that flag a yield
LOW_CHORDS = 2
#: force ratio between successive points of the kept loading path
LOADING_STEP = 1.05
#: the set check's allowance for an object's damper, in samples of the pads' last motion
DAMPER_SAMPLES = 0.5


def set_beyond_m(path: tuple[tuple[float, float], ...], force_n: float, advance_m: float,
                 step_m: float) -> float:
    """How far pads at ``advance_m`` with the force ``force_n`` stand beyond where the
    loading ``path`` first reached that force, less ``DAMPER_SAMPLES`` of the sample's own
    motion ``step_m``.  An elastic contact unloads along the path it loaded on (about 0); its
    damper holds the unloading force below the loading one by ``c v``, the pads by ``c v /
    k`` = ``(c / k) / dt`` samples' motion: within the allowance for a contact whose time
    constant is under half the hand's sample period (the grid's objects: 2-7 ms against
    12.5 ms).  A crushed object unloads along a path moved in by its dent.  Gain-free: the
    force only picks the point on the path."""
    i = bisect_left(path, force_n, key=_force)
    q_load = path[min(i, len(path) - 1)][1]
    return advance_m - q_load - DAMPER_SAMPLES * abs(step_m)


def _force(point: tuple[float, float]) -> float:
    return point[0]


def took_a_set(track: YieldTrack, window_m: float) -> bool:
    """Did the contact that ``track`` followed leave the object dented: at its last sample,
    pads standing more than one window (``window_m``) beyond the loading path
    (:func:`set_beyond_m`)?"""
    return bool(track.loading) and set_beyond_m(
        track.loading, track.force_n, track.advance_m, track.step_m) > window_m


def _loaded(path: tuple[tuple[float, float], ...], force_n: float,
            advance_m: float) -> tuple[tuple[float, float], ...]:
    """``path`` with ``(force_n, advance_m)`` added if the force passed its last point by
    ``LOADING_STEP``."""
    if path and force_n < LOADING_STEP * path[-1][0]:
        return path
    return (*path, (force_n, advance_m))


def step_yield(prev: YieldTrack, force_n: float, advance_m: float, motor_rad: float,
               window_m: float, stiffness_ratio: float,
               motor_prev_rad: float | None = None, set_check: bool = True) -> YieldTrack:
    """One hand sample of one finger: ``force_n`` the estimated total pad force at its end,
    ``advance_m`` the pads' force-weighted advance into the object over it
    (:func:`pad_advance_m`), ``motor_rad`` its motor angle (joint side) at its end and
    ``motor_prev_rad`` at its start (None: not known, no winding counted).  A chord is only
    judged while the motor wound in over it: a force falling while the servo lets go is an
    unloading, not a yield.  The episode's winding (the motor's inward motion, the sample
    in which the force was first seen included) is what :func:`flag_recharge_j` charges
    when the flag is raised.  ``set_check``: judge a contact that ends unflagged by the
    set it left (:func:`took_a_set`; the hand's ``yield_set_check``, on by default)."""
    if force_n <= 0.0:
        # the contact ended: unflagged, it is judged once more by the set it left
        if (set_check and prev.in_contact and not prev.yielding and stiffness_ratio > 0.0
                and took_a_set(prev, window_m)):
            return SET_FOUND
        return NO_CONTACT
    wound = (prev.wound_rad if prev.in_contact else 0.0) + (
        max(motor_rad - motor_prev_rad, 0.0) if motor_prev_rad is not None else 0.0)
    if not prev.in_contact:
        # the episode begins where the force is first seen: chords are measured from here
        # (the force jumps from zero at the first reading; that step is not a stiffness)
        return YieldTrack(in_contact=True, anchor_n=force_n, anchor_motor_rad=motor_rad,
                          wound_rad=wound, force_n=force_n, loading=((force_n, 0.0),))
    q = prev.advance_m + advance_m
    path = _loaded(prev.loading, force_n, q)
    span = q - prev.anchor_m
    if span < 0.0:
        # backing out: the next chord starts from the furthest-back point (an elastic
        # contact unloads and reloads along the same curve)
        return YieldTrack(True, q, q, force_n, prev.stiffest_n_per_m, motor_rad, 0,
                          prev.yielding, wound, force_n, advance_m, path)
    if span < window_m:
        return YieldTrack(True, q, prev.anchor_m, prev.anchor_n, prev.stiffest_n_per_m,
                          prev.anchor_motor_rad, prev.low_chords, prev.yielding, wound,
                          force_n, advance_m, path)
    chord = (force_n - prev.anchor_n) / span
    stiffest = max(prev.stiffest_n_per_m, chord)
    flat = (stiffness_ratio > 0.0 and stiffest > 0.0 and chord < stiffness_ratio * stiffest
            and motor_rad > prev.anchor_motor_rad)
    low = prev.low_chords + 1 if flat else 0
    return YieldTrack(True, q, q, force_n, stiffest, motor_rad, low,
                      prev.yielding or low >= LOW_CHORDS, wound, force_n, advance_m,
                      path)


def pad_advance_m(forces_n: tuple[float, float], places_m: tuple[float, float],
                  dtp_rad: float, distal_rad: float, proximal_length_m: float) -> float:
    """The pads' advance along their normals over a sample in which the proximal joint
    turned ``dtp_rad`` (distal bend held at ``distal_rad``), weighted by the pads' forces
    ``(proximal, distal)`` acting at ``places_m`` along them: the proximal pad at ``r``
    moves ``r dtp``, the distal pad at ``r`` moves ``(L cos t_d + r) dtp``."""
    fp, fd = forces_n
    total = fp + fd
    if total <= 0.0:
        return 0.0
    rp, rd = places_m
    lever = proximal_length_m * math.cos(distal_rad) + rd
    return (fp * rp + fd * lever) * dtp_rad / total


def yield_charge_j(x: tuple[float, ...], x_prev: tuple[float, ...],
                   yielding: tuple[bool, ...], torque_max_nm: float) -> float:
    """What the tank pays for the yielding fingers' last sample: ``tau_max`` times each one's
    inward motor motion (joint side), the servo's most work through the tendon."""
    return sum(yield_charges_j(x, x_prev, yielding, torque_max_nm))


def yield_charges_j(x: tuple[float, ...], x_prev: tuple[float, ...],
                    yielding: tuple[bool, ...], torque_max_nm: float) -> tuple[float, ...]:
    """:func:`yield_charge_j` per finger (0 for a finger not flagged)."""
    return tuple(torque_max_nm * max(a - b, 0.0) if y else 0.0
                 for a, b, y in zip(x, x_prev, yielding, strict=False))


def flag_recharge_j(before: tuple[YieldTrack, ...], after: tuple[YieldTrack, ...],
                    torque_max_nm: float) -> float:
    """What the tank pays when a finger's flag is raised: ``tau_max`` times the motor's
    inward motion over the episode before this sample (this sample's is
    :func:`yield_charge_j`'s), the servo's most work through the tendon over the advance
    the cells were trusted for.  What the cells charged for that advance is not taken off
    (the one-sample cap may have cut it, so it is not known to have been paid): the
    advance before the flag is charged twice over rather than short."""
    return sum(flag_recharges_j(before, after, torque_max_nm))


def flag_recharges_j(before: tuple[YieldTrack, ...], after: tuple[YieldTrack, ...],
                     torque_max_nm: float) -> tuple[float, ...]:
    """:func:`flag_recharge_j` per finger (0 for a finger not just flagged)."""
    return tuple(torque_max_nm * b.wound_rad if a.yielding and not b.yielding else 0.0
                 for b, a in zip(before, after, strict=False))


__all__ = ["NO_CONTACT", "SET_FOUND", "YieldTrack", "flag_recharge_j", "flag_recharges_j",
           "pad_advance_m", "set_beyond_m", "step_yield", "took_a_set", "yield_charge_j",
           "yield_charges_j"]
