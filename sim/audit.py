"""Physical energy audit of the hand's environment port: work the fingers do on the object.

Computed from the simulated physics only (finger geometry and the contact object's law),
never from controller code, so a controller's own energy books can be checked against it.

The object is the compliant body of :mod:`sim.contact`: along each pad's contact normal it
pushes back with ``k s d + c s d'`` (``d`` the penetration depth, ``s`` the engaged fraction
of the pad, never a pull), plus ``k_core s (d - d_core)`` past its rigid core's depth. The
energy it takes from a finger over a physics step in which the depth goes from ``d0`` to
``d1`` is the force times the depth change: trapezoidal in the elastic part on each side of
the core's depth (exact for this piecewise-linear spring), the damper at the mean rate ``(d1
- d0) / dt``.  A block's core is met element by element (``sim.contact.block_core``): its
springs ``k_core s_c d_c`` act on the part of the pad pressed past the core (fraction ``s_c``,
mean depth ``d_c`` past it), and their work is counted the same way on ``d_c``
(:func:`core_work_j`).
A yielding object (``yield_force_n > 0``, :mod:`sim.crush`) pushes back with its skin's spring
on the elastic depth ``d - dent`` (held at the yield level while the dent grows) and its damper
on that depth's rate; the dent under each pad is read from the physics state
(``FingerState.crush_m``, grown by the depth of the state itself), and the elastic force's mean
is exact between the law's kinks, so the work that crushes the dent is counted as delivered to
the object, and is never taken back.
Positive work is energy delivered to the environment, negative work energy taken from it
(the object's springs pushing the finger back).

Usage (``SimHand`` does this at every physics step when its audit is on)::

    before = pad_depths(fs0, params, obj)
    after = pad_depths(fs1, params, obj)
    w = object_work_j(before, after, obj, dt_s)
"""

from __future__ import annotations

import math

from sim.contact import ContactObject, block_core, mean_spring_force, pad_contact
from sim.crush import pad_dent, yield_pad_work_j
from sim.params import FingerParams
from sim.readout import distal_origin
from sim.state import FingerState

_PROX_PAD_START_M = 0.010  # where the proximal pad starts along the link (as sim.finger)

#: (stiffness scale, depth m) of the proximal and distal pads, then their dents m (a yielding
#: object's; 0 for an elastic one), then (engaged fraction, mean depth m) of the parts of the
#: proximal and distal pads pressed past a block's core (0 for a cylinder)
PadDepths = tuple[float, float, float, float, float, float, float, float, float, float]
NO_CONTACT: PadDepths = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def pad_depths(state: FingerState, p: FingerParams, obj: ContactObject) -> PadDepths:
    """Engaged fraction and penetration depth of both pads of one finger in ``obj``."""
    if obj.kind == "none":
        return NO_CONTACT
    phi = state.prox_rad
    cphi, sphi = math.cos(phi), math.sin(phi)
    po = p.pad_offset_m
    s_p, d_p, _, _, _ = pad_contact(obj, cphi, sphi, _PROX_PAD_START_M, po,
                                    p.proximal_rigid_m, po)
    x, y, ca, sa = distal_origin(state, p)
    ax, ay = x - sa * po, y + ca * po
    bx, by = ax + ca * p.distal_length_m, ay + sa * p.distal_length_m
    s_d, d_d, _, _, _ = pad_contact(obj, cphi, sphi, ax, ay, bx, by)
    d_p = max(d_p, 0.0)
    d_d = max(d_d, 0.0)
    cs_p = cd_p = cs_d = cd_d = 0.0
    if obj.kind == "block":
        cs_p, cd_p, _ = block_core(obj, cphi, sphi, _PROX_PAD_START_M, po, p.proximal_rigid_m,
                                   po)
        cs_d, cd_d, _ = block_core(obj, cphi, sphi, ax, ay, bx, by)
    if obj.yield_force_n > 0.0:
        crush_p, crush_d = state.crush_m
        return (s_p, d_p, s_d, d_d, pad_dent(obj, crush_p, d_p), pad_dent(obj, crush_d, d_d),
                cs_p, cd_p, cs_d, cd_d)
    return (s_p, d_p, s_d, d_d, 0.0, 0.0, cs_p, cd_p, cs_d, cd_d)


def _pad_work(s0: float, d0: float, s1: float, d1: float, obj: ContactObject,
              dt_s: float, core: bool = True) -> float:
    if d0 <= 0.0 and d1 <= 0.0:
        return 0.0
    c = obj.damping_n_s_per_m
    dd = d1 - d0
    elastic = mean_spring_force(obj, s0, d0, s1, d1, core)
    damping = c * 0.5 * (s0 + s1) * dd / dt_s if dt_s > 0.0 else 0.0
    force = max(elastic + damping, 0.0)
    return force * dd


def object_work_j(before: PadDepths, after: PadDepths, obj: ContactObject,
                  dt_s: float) -> float:
    """Work the finger did on the object over one physics step (+ delivered, - taken)."""
    if obj.kind == "none":
        return 0.0
    core = obj.kind != "block"  # a block's core: its own springs, element by element
    if obj.yield_force_n > 0.0:
        w = (yield_pad_work_j(before[0], before[1], before[4], after[0], after[1], after[4],
                              obj, dt_s, core)
             + yield_pad_work_j(before[2], before[3], before[5], after[2], after[3], after[5],
                                obj, dt_s, core))
    else:
        w = (_pad_work(before[0], before[1], after[0], after[1], obj, dt_s, core)
             + _pad_work(before[2], before[3], after[2], after[3], obj, dt_s, core))
    if core:
        return w
    return (w + core_work_j(before[6], before[7], after[6], after[7], obj)
            + core_work_j(before[8], before[9], after[8], after[9], obj))


def core_work_j(s0: float, d0: float, s1: float, d1: float, obj: ContactObject) -> float:
    """Work a pad did on a block's core over one step, its pressed-past part going from
    fraction ``s0`` at mean depth ``d0`` to ``s1``, ``d1``: the core's springs ``k_core s d``
    (trapezoidal: exact at a constant fraction) times the depth change."""
    if d0 <= 0.0 and d1 <= 0.0:
        return 0.0
    kc = obj.core_stiffness_n_per_m
    return kc * 0.5 * (s0 * d0 + s1 * d1) * (d1 - d0)


__all__ = ["NO_CONTACT", "PadDepths", "core_work_j", "object_work_j", "pad_depths"]
