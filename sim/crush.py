"""A yielding object: the compliant skin of :mod:`sim.contact` crushed plastically by the pads.

With ``yield_force_n > 0`` (``F_y``, N) the object's skin (stiffness ``k`` N/m, damping ``c``
N s/m) takes a permanent dent under each pad (``crush_m``, m, the proximal and the distal pad
of each finger, kept in ``FingerState.crush_m``; it never shrinks).  For a pad at geometric
depth ``d`` (m, from the object's original surface, as the elastic object) with engaged
fraction ``s`` (0..1):

* dent: ``crush = max(crush_before, (k d - F_y) / (k + H))``, ``H`` =
  ``yield_hardening_n_per_m`` (N/m, default 0: perfectly plastic).  The dent grows exactly as
  far as keeps the skin's spring force per engaged fraction at the yield level
  ``F_y + H crush`` (a return mapping; ``s`` scales force and yield alike, so the dent does
  not depend on it);
* skin spring: ``k s (d - crush)`` while the pad presses the skin (``d > crush``), 0 inside
  the dent (no pull);
* rigid core: ``k_core s (d - core_depth_m)`` past ``core_depth_m`` from the original surface;
  the core does not yield;
* damper: ``c s e'`` on the rate of the skin's elastic depth ``e = d - crush`` (while pressing
  the skin): the elastic object's ``c s d'`` while the dent holds, ``c s d' H / (k + H)`` (0
  when perfectly plastic) while it grows;
* the pad's force ``skin + core + damper`` never pulls.

The work that pushes the dent in, ``s (F_y + H crush) d(crush)`` (J), is dissipated: the
object never gives it back (a finger withdrawn from a dented object gets back only the skin's
elastic energy ``k s e^2 / 2``).  ``yield_force_n = 0`` is the elastic object: no dent, the
elastic code paths bit for bit.

The finger step integrates the law linearly implicitly, as the elastic one: the dent of the
state is updated from the depth at the start of the step, the tangent stiffness (and damping)
is the elastic ``k s`` while the dent holds, the plastic ``k s H / (k + H)`` while it grows.
:func:`mean_yield_force` is the physical audit's exact mean of the elastic force over a step.
"""

from __future__ import annotations

from sim.contact import ContactObject, block_core, pad_spring


def pad_dent(obj: ContactObject, crush_m: float, depth_m: float) -> float:
    """The dent under a pad ``depth_m`` deep whose dent so far is ``crush_m`` (never less)."""
    k = obj.stiffness_n_per_m
    plastic = (k * depth_m - obj.yield_force_n) / (k + obj.yield_hardening_n_per_m)
    return plastic if plastic > crush_m else crush_m


def yield_pad_spring(obj: ContactObject, scale: float, depth_m: float,
                     crush_m: float, core: bool = True) -> tuple[float, float, float, float]:
    """(elastic force N, tangent stiffness N/m, damping factor, dent m) of a pad ``depth_m``
    deep, ``scale`` engaged, whose dent so far is ``crush_m``: the skin crushed to the yield
    level, plus the core; the damping factor multiplies ``c s`` (the rate of elastic depth)."""
    k = obj.stiffness_n_per_m
    h = obj.yield_hardening_n_per_m
    dent = pad_dent(obj, crush_m, depth_m)
    rate = 1.0
    if dent > crush_m:  # the dent grows with the depth: plastic tangent
        crush_m = dent
        rate = h / (k + h)
    force = 0.0
    ke = 0.0
    elastic = depth_m - crush_m
    if elastic > 0.0:
        force = k * scale * elastic
        ke = k * scale * rate
    else:
        rate = 0.0
    if core and depth_m > obj.core_depth_m:
        kc = obj.core_stiffness_n_per_m * scale
        force += kc * (depth_m - obj.core_depth_m)
        ke += kc
    return force, ke, rate, crush_m


def pad_law(obj: ContactObject, scale: float, depth_m: float,
            crush_m: float, core: bool = True) -> tuple[float, float, float, float]:
    """(elastic force N, tangent stiffness N/m, damping N s/m, dent m) of a pad ``depth_m``
    deep, ``scale`` engaged, whose dent so far is ``crush_m``: the yielding law, or the
    elastic object's (``sim.contact.pad_spring``, no dent) when ``yield_force_n`` is 0
    (``core`` False: without the core, which a block meets element by element)."""
    if obj.yield_force_n > 0.0:
        fe, ke, rate, crush_m = yield_pad_spring(obj, scale, depth_m, crush_m, core)
        return fe, ke, obj.damping_n_s_per_m * scale * rate, crush_m
    fe, ke = pad_spring(obj, scale, depth_m, core)
    return fe, ke, obj.damping_n_s_per_m * scale, crush_m


def block_law(obj: ContactObject, scale: float, depth_m: float, t: float, core_scale: float,
              core_depth_m: float, core_t: float, crush_m: float
              ) -> tuple[float, float, float, float, float]:
    """(elastic force N, tangent stiffness N/m, damping N s/m, where t, dent m) of a pad on a
    block: the skin's law on the pressed part (``sim.crush.pad_law`` without its core) plus
    the core's springs ``core_stiffness_n_per_m`` on the part pressed past the core, the
    resultant at the two forces' centre."""
    fe, ke, ce, crush_m = pad_law(obj, scale, depth_m, crush_m, False)
    if core_depth_m > 0.0:
        kc = obj.core_stiffness_n_per_m * core_scale
        fc = kc * core_depth_m
        t = (fe * t + fc * core_t) / (fe + fc)
        fe += fc
        ke += kc
    return fe, ke, ce, t, crush_m


def pad_force(obj: ContactObject, cphi: float, sphi: float, ax: float, ay: float, bx: float,
              by: float, scale: float, depth_m: float, t: float,
              crush_m: float) -> tuple[float, float, float, float, float]:
    """(elastic force N, tangent stiffness N/m, damping N s/m, where t, dent m) of a pad A->B
    that ``sim.contact.pad_contact`` found ``depth_m`` deep, ``scale`` engaged, at ``t``: a
    block's law (:func:`block_law`, its core met element by element) or :func:`pad_law`."""
    if obj.kind == "block":
        sc, dc, tc = block_core(obj, cphi, sphi, ax, ay, bx, by)
        return block_law(obj, scale, depth_m, t, sc, dc, tc, crush_m)
    fe, ke, ce, crush_m = pad_law(obj, scale, depth_m, crush_m)
    return fe, ke, ce, t, crush_m


def _path_force(obj: ContactObject, scale: float, depth_m: float, crush_m: float,
                core: bool = True) -> float:
    return yield_pad_spring(obj, scale, depth_m, crush_m, core)[0]


def mean_yield_force(obj: ContactObject, s0: float, d0: float, c0: float, s1: float,
                     d1: float, core: bool = True) -> float:
    """The elastic force's mean as the depth goes d0 -> d1 from dent ``c0`` (the engaged
    fraction s0 -> s1 linearly), the dent following the depth: trapezoidal between the law's
    kinks (the skin met at ``c0``, the yield, the core), so its product with d1 - d0 is the
    work on the skin and core, exact at a constant fraction."""
    k = obj.stiffness_n_per_m
    f_prev = _path_force(obj, s0, d0, c0, core)
    dd = d1 - d0
    if dd == 0.0:
        return 0.5 * (f_prev + _path_force(obj, s1, d1, c0, core))
    d_yield = c0 + (obj.yield_force_n + obj.yield_hardening_n_per_m * c0) / k
    cuts = sorted(a for a in ((c0 - d0) / dd, (d_yield - d0) / dd,
                              (obj.core_depth_m - d0) / dd) if 0.0 < a < 1.0)
    total = 0.0
    a_prev = 0.0
    for a in cuts:
        f = _path_force(obj, s0 + a * (s1 - s0), d0 + a * dd, c0, core)
        total += 0.5 * (f_prev + f) * (a - a_prev)
        f_prev = f
        a_prev = a
    return total + 0.5 * (f_prev + _path_force(obj, s1, d1, c0, core)) * (1.0 - a_prev)


def yield_pad_work_j(s0: float, d0: float, c0: float, s1: float, d1: float, c1: float,
                     obj: ContactObject, dt_s: float, core: bool = True) -> float:
    """Work a pad did on a yielding object over one step (``c0``/``c1`` the dents of the two
    states): the elastic force's exact mean plus the damper on the rate of elastic depth, never
    a pull, times the depth change."""
    if d0 <= 0.0 and d1 <= 0.0:
        return 0.0
    dd = d1 - d0
    e0 = d0 - c0 if d0 > c0 else 0.0
    e1 = d1 - c1 if d1 > c1 else 0.0
    elastic = mean_yield_force(obj, s0, d0, c0, s1, d1, core)
    c = obj.damping_n_s_per_m
    damping = c * 0.5 * (s0 + s1) * (e1 - e0) / dt_s if dt_s > 0.0 else 0.0
    force = max(elastic + damping, 0.0)
    return force * dd
