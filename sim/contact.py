"""Objects the finger touches, penalty contact on the sensor pads, and the 9 pressure readings.

The finger lives in its own plane: x along the finger at rest (the palm normal), +y towards the
side it curls to; the base axle is the origin.  A ``cylinder`` is a circle of ``radius_m``
centred at (x_m, y_m); a ``block`` is the half-plane y >= y_m (a flat face parallel to the
finger at rest; x_m is not used). Contact is a compliant (spring ``stiffness_n_per_m`` +
damper ``damping_n_s_per_m``) normal force on each link's pad; pressed deeper than
``core_depth_m`` a pad meets the object's rigid core and ``core_stiffness_n_per_m`` adds to
the spring (``pad_spring``), so the servo's full torque cannot push a finger through the
object. A cylinder touches a pad at one point; a block presses a pad as a Winkler foundation
(stiffness spread uniformly along the pad), whose resultant acts at the centroid of the
pressed part. The block's core lies under the bed of springs: each element meets it at its own
depth ``core_depth_m`` (:func:`block_core`, ``sim.crush.block_law``), so a pad pressed into
the face edge first meets the core with its deepest point, with a stiffness that grows from
zero as more of the pad reaches the core. (Met on the pressed part's mean depth, as a
cylinder's single point meets it, a pad tilted into the face went in tip first 2-3 core depths
deep, curled past the perpendicular and stayed there: the lock of issue 13.)

A yielding object (``yield_force_n`` > 0, N) has a skin that crushes plastically: each pad
leaves a permanent dent (m) and the skin's spring pushes back ``k s (d - dent)``, at most the
yield level ``s (yield_force_n + yield_hardening_n_per_m * dent)``; the work into the dent is
never returned (the law, with units, in :mod:`sim.crush`).

Pressure: each link's contact force lands at a point along the link; every sensor of that link
reads ``pressure_per_n * F * kernel(distance)``, a narrow Gaussian (the two sensors nearest a
cylinder read strongly) plus a weak exponential tail (the rubber spreads the load to
neighbours weakly), as in the report's Fig. 3.6.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sim.params import FingerParams
from teleop.config.hand import ObjectConfig


@dataclass(frozen=True, slots=True)
class ContactObject:
    """An object in the finger's plane (same meaning as ``teleop.config.hand.ObjectConfig``)."""

    kind: str = "none"  # "none" | "cylinder" | "block"
    x_m: float = 0.045
    y_m: float = 0.03
    radius_m: float = 0.02
    stiffness_n_per_m: float = 2000.0
    damping_n_s_per_m: float = 5.0
    core_depth_m: float = 0.012
    core_stiffness_n_per_m: float = 2e5
    yield_force_n: float = 0.0  # > 0: the skin crushes plastically (sim.crush); 0: elastic
    yield_hardening_n_per_m: float = 0.0


NO_OBJECT = ContactObject()


def contact_object_from_config(cfg: ObjectConfig) -> ContactObject:
    """The contact object described by the config section ``hand.sim.object``."""
    return ContactObject(kind=cfg.kind, x_m=cfg.x_m, y_m=cfg.y_m, radius_m=cfg.radius_m,
                         stiffness_n_per_m=cfg.stiffness_n_per_m,
                         damping_n_s_per_m=cfg.damping_n_s_per_m,
                         core_depth_m=cfg.core_depth_m,
                         core_stiffness_n_per_m=cfg.core_stiffness_n_per_m,
                         yield_force_n=cfg.yield_force_n,
                         yield_hardening_n_per_m=cfg.yield_hardening_n_per_m)


def pad_spring(obj: ContactObject, scale: float, depth_m: float,
               core: bool = True) -> tuple[float, float]:
    """(elastic force N, tangent stiffness N/m) of a pad ``depth_m`` deep, ``scale`` engaged:
    the skin's spring, plus the core's once ``core_depth_m`` is passed (``core``: a block's
    core is met element by element instead, :func:`block_core`)."""
    ke = obj.stiffness_n_per_m * scale
    force = ke * depth_m
    if core and depth_m > obj.core_depth_m:
        kc = obj.core_stiffness_n_per_m * scale
        force += kc * (depth_m - obj.core_depth_m)
        ke += kc
    return force, ke




def mean_spring_force(obj: ContactObject, s0: float, d0: float, s1: float, d1: float,
                      core: bool = True) -> float:
    """The pad spring's mean force as the depth goes d0 -> d1 (the engaged fraction s0 -> s1
    linearly): trapezoidal on each side of the core's depth, so its product with d1 - d0 is
    the spring's exact work at a constant fraction."""
    f0 = pad_spring(obj, s0, d0, core)[0]
    f1 = pad_spring(obj, s1, d1, core)[0]
    dc = obj.core_depth_m
    if (d0 - dc) * (d1 - dc) >= 0.0:
        return 0.5 * (f0 + f1)
    a = (dc - d0) / (d1 - d0)
    fc = pad_spring(obj, s0 + a * (s1 - s0), dc, core)[0]
    return 0.5 * ((f0 + fc) * a + (fc + f1) * (1.0 - a))

def pad_contact(obj: ContactObject, cphi: float, sphi: float, ax: float, ay: float, bx: float,
                by: float) -> tuple[float, float, float, float, float]:
    """Penetration of one pad segment A->B (proximal frame) into ``obj``.

    Returns ``(stiffness_scale, depth_m, t, nx, ny)``: the contact force is
    ``k * depth`` (+ damping) along (nx, ny) (proximal frame, pushing the finger away), applied
    at A + t (B - A); ``stiffness_scale`` (0..1) is the fraction of the pad's stiffness engaged
    (1 for a point contact).  ``depth_m <= 0`` means no contact.  A cylinder whose centre a
    pad has been pushed past (on or behind the pad's line) is still pushed against along the
    pad's normal, deeper as it goes (up to twice the radius), never flipped.
    """
    if obj.kind == "cylinder":
        # object centre in the proximal frame
        cx = cphi * obj.x_m + sphi * obj.y_m
        cy = -sphi * obj.x_m + cphi * obj.y_m
        ex = bx - ax
        ey = by - ay
        t = ((cx - ax) * ex + (cy - ay) * ey) / (ex * ex + ey * ey)
        if 0.0 < t < 1.0:
            # the centre on or behind the pad's line (the pad pushed past it): the depth
            # keeps growing along the pad normal instead of flipping the contact normal
            el = math.sqrt(ex * ex + ey * ey)
            mx, my = -ey / el, ex / el  # the pad face's outward normal
            h = (cx - ax) * mx + (cy - ay) * my
            if h <= 0.0:
                if h <= -obj.radius_m:
                    return 0.0, 0.0, 0.0, 0.0, 0.0
                return 1.0, obj.radius_m - h, t, -mx, -my
        t = 0.0 if t < 0.0 else (1.0 if t > 1.0 else t)
        px = ax + t * ex
        py = ay + t * ey
        dx = px - cx
        dy = py - cy
        dist = math.sqrt(dx * dx + dy * dy)
        depth = obj.radius_m - dist
        if depth <= 0.0 or dist < 1e-12:
            return 0.0, 0.0, 0.0, 0.0, 0.0
        return 1.0, depth, t, dx / dist, dy / dist
    if obj.kind == "block":
        return half_plane_contact(obj.y_m, cphi, sphi, ax, ay, bx, by)
    return 0.0, 0.0, 0.0, 0.0, 0.0


def half_plane_contact(face_m: float, cphi: float, sphi: float, ax: float, ay: float,
                       bx: float, by: float) -> tuple[float, float, float, float, float]:
    """:func:`pad_contact` of a pad A->B in the half-plane world y >= ``face_m`` (a bed of
    springs: the engaged fraction, the mean depth of the pressed part, its centroid)."""
    # world y of a proximal-frame point = s x + c y
    pa = sphi * ax + cphi * ay - face_m
    pb = sphi * bx + cphi * by - face_m
    nx, ny = -sphi, -cphi
    if pa <= 0.0 and pb <= 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0
    if pa > 0.0 and pb > 0.0:
        mean = 0.5 * (pa + pb)
        t = (pa + 2.0 * pb) / (3.0 * (pa + pb))
        return 1.0, mean, t, nx, ny
    if pb > 0.0:
        t0 = pa / (pa - pb)
        frac = 1.0 - t0
        return frac, 0.5 * pb, t0 + frac * 2.0 / 3.0, nx, ny
    t0 = pa / (pa - pb)
    return t0, 0.5 * pa, t0 / 3.0, nx, ny


def block_core(obj: ContactObject, cphi: float, sphi: float, ax: float, ay: float, bx: float,
               by: float) -> tuple[float, float, float]:
    """(engaged fraction, mean depth m, where t) of the part of a pad A->B pressed past a
    block's rigid core: every element of the bed of springs meets the core at its own depth
    ``core_depth_m`` (the pad's deepest point first), not at the pressed part's mean depth."""
    sc, dc, tc, _, _ = half_plane_contact(obj.y_m + obj.core_depth_m, cphi, sphi, ax, ay, bx, by)
    return sc, dc, tc


def sensor_pressures(params: FingerParams, prox_force_n: float, prox_x_m: float,
                     dist_force_n: float, dist_x_m: float) -> tuple[float, ...]:
    """The 9 raw pressure readings (5 proximal, 4 distal) from the two links' contact forces."""
    gain = params.pressure_per_n
    inv2s2 = 0.5 / (params.pressure_sigma_m ** 2)
    tail = params.pressure_tail
    inv_tail = 1.0 / params.pressure_tail_m
    out: list[float] = []
    for force, where, xs in ((prox_force_n, prox_x_m, params.proximal_sensor_x_m),
                             (dist_force_n, dist_x_m, params.distal_sensor_x_m)):
        if force <= 0.0:
            out.extend(0.0 for _ in xs)
            continue
        for xk in xs:
            d = xk - where
            out.append(gain * force * (math.exp(-d * d * inv2s2)
                                       + tail * math.exp(-abs(d) * inv_tail)))
    return tuple(out)
