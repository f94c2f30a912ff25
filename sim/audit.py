"""Physical energy audit of the hand's environment port: work the fingers do on the object.

Computed from the simulated physics only (finger geometry and the contact object's law),
never from controller code, so a controller's own energy books can be checked against it.

The object is the compliant body of :mod:`sim.contact`: along each pad's contact normal it
pushes back with ``k s d + c s d'`` (``d`` the penetration depth, ``s`` the engaged fraction
of the pad, never a pull), plus ``k_core s (d - d_core)`` past its rigid core's depth. The
energy it takes from a finger over a physics step in which the depth goes from ``d0`` to
``d1`` is the force times the depth change: trapezoidal in the elastic part on each side of
the core's depth (exact for this piecewise-linear spring), the damper at the mean rate ``(d1
- d0) / dt``.  That is exact for a point contact (a cylinder).  A block is a bed of springs
along the pad, each element pressed to its own depth: an elastic block's skin and core
(``sim.contact.block_core``: met element by element) are counted as the change of the energy
the bed holds (:func:`bed_energy_j`), whose gradient the block's contact law is; force times
the change of the pressed part's *mean* depth, counted until 2026-11-28, read about half of
it for a pad pressed in tilted.  A yielding block is still counted that way (its dent is per
pad), the core's springs ``k_core s_c d_c`` on the mean depth ``d_c`` past the core
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
#: proximal and distal pads pressed past a block's core (0 for a cylinder), then the energy J
#: an elastic block's bed of springs holds under the proximal and the distal pad
#: (:func:`bed_energy_j`; 0 otherwise)
PadDepths = tuple[float, float, float, float, float, float, float, float, float, float, float,
                  float]
NO_CONTACT: PadDepths = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def squared_depth_integral(a_m: float, b_m: float) -> float:
    """``int_0^1 max(a + (b - a) u, 0)^2 du`` (m^2): the squared depth of a straight pad
    whose depth goes linearly from ``a_m`` to ``b_m`` along it, over the pad's fraction."""
    if a_m > 0.0 and b_m > 0.0:
        return (a_m * a_m + a_m * b_m + b_m * b_m) / 3.0
    if b_m > 0.0:
        return b_m * b_m * b_m / (3.0 * (b_m - a_m))
    if a_m > 0.0:
        return a_m * a_m * a_m / (3.0 * (a_m - b_m))
    return 0.0


def bed_energy_j(obj: ContactObject, cphi: float, sphi: float, ax: float, ay: float, bx: float,
                 by: float) -> float:
    """Energy an elastic block holds under a straight pad A->B (proximal frame): its bed of
    springs, ``k`` per unit of pad fraction and ``k_core`` more past the core's depth, each
    element pressed to its own depth, ``int k d^2 / 2 + k_core (d - d_core)^2 / 2`` over the
    pad (closed form: the depth is linear along it).  The block's contact law
    (``sim.crush.block_law``: ``k s d_mean`` at the pressed part's centroid, plus the core's
    springs at theirs) is this energy's gradient, so the work a pad does on the block between
    two states is its difference."""
    pa = sphi * ax + cphi * ay - obj.y_m
    pb = sphi * bx + cphi * by - obj.y_m
    dc = obj.core_depth_m
    return 0.5 * (obj.stiffness_n_per_m * squared_depth_integral(pa, pb)
                  + obj.core_stiffness_n_per_m * squared_depth_integral(pa - dc, pb - dc))


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
    cs_p = cd_p = cs_d = cd_d = e_p = e_d = 0.0
    if obj.kind == "block":
        cs_p, cd_p, _ = block_core(obj, cphi, sphi, _PROX_PAD_START_M, po, p.proximal_rigid_m,
                                   po)
        cs_d, cd_d, _ = block_core(obj, cphi, sphi, ax, ay, bx, by)
    if obj.yield_force_n > 0.0:
        crush_p, crush_d = state.crush_m
        return (s_p, d_p, s_d, d_d, pad_dent(obj, crush_p, d_p), pad_dent(obj, crush_d, d_d),
                cs_p, cd_p, cs_d, cd_d, 0.0, 0.0)
    if obj.kind == "block":
        e_p = bed_energy_j(obj, cphi, sphi, _PROX_PAD_START_M, po, p.proximal_rigid_m, po)
        e_d = bed_energy_j(obj, cphi, sphi, ax, ay, bx, by)
    return (s_p, d_p, s_d, d_d, 0.0, 0.0, cs_p, cd_p, cs_d, cd_d, e_p, e_d)


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


def _bed_work(b: PadDepths, a: PadDepths, i: int, obj: ContactObject, dt_s: float) -> float:
    """Work pad ``i`` (0 proximal, 1 distal) did on an elastic block over one step: the
    change of the energy its bed of springs holds, plus the damper on the pressed part's mean
    depth rate; nothing while the contact force is clamped off (never a pull)."""
    s0, d0, s1, d1 = b[2 * i], b[2 * i + 1], a[2 * i], a[2 * i + 1]
    if d0 <= 0.0 and d1 <= 0.0:
        return 0.0
    dd = d1 - d0
    elastic = (mean_spring_force(obj, s0, d0, s1, d1, False) + obj.core_stiffness_n_per_m
               * 0.5 * (b[6 + 2 * i] * b[7 + 2 * i] + a[6 + 2 * i] * a[7 + 2 * i]))
    damping = obj.damping_n_s_per_m * 0.5 * (s0 + s1) * dd / dt_s if dt_s > 0.0 else 0.0
    if elastic + damping <= 0.0:
        return 0.0
    return (a[10 + i] - b[10 + i]) + damping * dd


def object_work_j(before: PadDepths, after: PadDepths, obj: ContactObject,
                  dt_s: float) -> float:
    """Work the finger did on the object over one physics step (+ delivered, - taken)."""
    if obj.kind == "none":
        return 0.0
    if obj.kind == "block" and obj.yield_force_n <= 0.0:
        return (_bed_work(before, after, 0, obj, dt_s)
                + _bed_work(before, after, 1, obj, dt_s))
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


__all__ = ["NO_CONTACT", "PadDepths", "bed_energy_j", "core_work_j", "object_work_j",
           "pad_depths", "squared_depth_integral"]
