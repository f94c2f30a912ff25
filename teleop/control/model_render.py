"""Master side of model-mediated rendering: the hand's contact model, rendered at 1 kHz.

The controller forwards each finger's model as ``(contact_rad, k)`` with ``k`` in N of trigger
force per rad of set-point beyond the contact angle.  The master maps its own trigger closing
``q`` to set-points with the transparency layer's map ``theta_i(q)`` (the controller's map:
same parameters) and renders::

    F_model(q) = combine_i k_i max(theta_i(q) - contact_i, 0)  +  b v   (in contact)

a function of ``q`` alone, so (continuous time) lossless: a grasp takes from the operator
exactly what its release gives back, however long the network delay.  ``b = damping_periods
* K * dt`` with ``K = max_i k_i G`` the rendered stiffness in N/m (``G`` = set-point rad per
m of trigger): more than ``K dt / 2`` keeps the sampled spring passive (Colgate and Schenkel,
1997).

The spring force is clipped at the trigger's ``force_max_n``.  The stored energy of the rendered
model at ``q`` is ``E(q) = int_0^q F_model``, integrated by trapezoids over the set-point (24
steps from the first contact angle; every enabled finger has the same set-point, the map is
linear, ``map_exponent = 1``, and the controller sends no model otherwise).  The master's tank keeps
``E(q)`` before it sends any quantum on, so it can always pay the release back.

Parameter updates are phased in: the rendered parameters move towards the received ones by
the fraction ``alpha = a0 * 2^-j`` (``a0 = min(1, rate * dt / |F_new(q) - F(q)|)``, the
smallest ``j <= 6``, else not at all this sample) for which the rendered force at the present
``q`` changes by at most ``rate * dt`` (``rate``: ``force_rate_n_per_s`` for an update that
raises the force, ``force_drop_rate_n_per_s`` for one that lowers it) and
the stored energy stays within what the tank holds above its minimum (or does not rise): an
update that raises the stored energy is paid from the master tank, as the tank allows.  A
finger whose rendered stiffness is 0 takes the new contact angle at once (no force change).
A model withdrawn by the hand (received stiffness 0: the object went, or the estimate
diverged and was dropped) ramps out at the same rate limit while the delayed measured force
takes over (the displayed force is the larger of the two), so the hand-over has no step down.
When a watchdog has cut the link (the command's force is exactly 0: liveliness lost, or a
timeout ramp at its end) a withdrawn model goes at once, like the force; a timeout ramp on
its way scales the received stiffness down and is followed at the rate limit.

The passivity argument does not depend on any of this: the master's tank pays the exact port
work of whatever force is displayed (``teleop.control.two_layer``).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from teleop.control.interface import ControlParams
from teleop.control.transparency_layer import grip_to_setpoints
from teleop.frozen import fast_init

Triple = tuple[float, float, float]
_ENVELOPE_STEPS = 24
_ALPHAS = (1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125, 0.015625)


@fast_init
@dataclass(frozen=True, slots=True)
class RenderState:
    """The model being rendered, per finger, and the share of the received one it has."""

    contact_rad: Triple = (0.0, 0.0, 0.0)
    stiffness_n_per_rad: Triple = (0.0, 0.0, 0.0)
    phase: float = 0.0  # rendered / received stiffness summed over fingers (0: no model)


def map_gain_rad_per_m(p: ControlParams) -> float:
    """``G``: set-point rad per m of trigger closing (linear map)."""
    return abs(p.closed_angle_rad - p.open_angle_rad) / p.trigger_travel_m


def setpoint_rad(p: ControlParams, q_m: float) -> float:
    """The set-point every enabled finger gets at trigger closing ``q_m`` (the open angle
    when none is enabled)."""
    th = grip_to_setpoints(q_m, p)
    on = p.finger_enable
    for i in range(3):
        if on[i]:
            return th[i]
    return p.open_angle_rad


def model_force_n(r: RenderState, p: ControlParams, q_m: float) -> float:
    """The rendered spring force at ``q_m`` (no damping), at most ``force_max_n``."""
    return _force_at(r, p, setpoint_rad(p, q_m))


#: the energies of the last few :func:`model_energy_j` calls: the inputs' bytes -> (params,
#: energy).  A held grasp asks for the same energy at every tick, and a hand whose encoder
#: reading flickers between two counts asks for two or three in turn.  Emptied when full
#: (a plain dict, so a reader in another thread sees an entry whole or not at all)
_energies: dict[bytes, tuple[ControlParams, float]] = {}
_ENERGIES_MAX = 8


def model_energy_j(r: RenderState, p: ControlParams, q_m: float) -> float:
    """The stored energy of the rendered model at ``q_m``: ``int_0^q F_model`` (see module)."""
    key = struct.pack("<7d", q_m, *r.contact_rad, *r.stiffness_n_per_rad)  # bit for bit
    hit = _energies.get(key)
    if hit is not None and hit[0] is p:
        return hit[1]
    e = _model_energy_j(r, p, q_m)
    if len(_energies) >= _ENERGIES_MAX:
        _energies.clear()
    _energies[key] = (p, e)
    return e


def _model_energy_j(r: RenderState, p: ControlParams, q_m: float) -> float:
    on = [i for i in range(3) if p.finger_enable[i] and r.stiffness_n_per_rad[i] > 0.0]
    if not on:
        return 0.0
    t_end, t0 = setpoint_rad(p, q_m), min(r.contact_rad[i] for i in on)
    if t_end <= t0:
        return 0.0
    n = _ENVELOPE_STEPS
    h = (t_end - t0) / n
    terms, how, f_max = _terms(r, p), p.force_combine, p.force_max_n
    if how == "max" and len(terms) == 3:  # the default, unrolled: same operations and order
        (k0, c0), (k1, c1), (k2, c2) = terms
        # the trapezoids' sum as the general path below forms it, without the list
        total = 0
        f_first = f_last = 0.0
        for j in range(n + 1):  # max/min spelled as the comparisons they make (same bits)
            th = t0 + j * h
            d0, d1, d2 = th - c0, th - c1, th - c2
            x = k0 * (0.0 if d0 < 0.0 else d0)  # max(d0, 0.0)
            x1 = k1 * (0.0 if d1 < 0.0 else d1)
            x2 = k2 * (0.0 if d2 < 0.0 else d2)
            if x1 > x:  # max(x, x1, x2)
                x = x1
            if x2 > x:
                x = x2
            if x < 0.0:  # min(max(x, 0.0), f_max)
                x = 0.0
            if f_max < x:
                x = f_max
            total += x
            if j == 0:
                f_first = x
            f_last = x
        return h * (total - 0.5 * (f_first + f_last)) / map_gain_rad_per_m(p)
    f = [_force_of(terms, how, f_max, t0 + j * h) for j in range(n + 1)]
    total = 0
    for x in f:  # left to right, one rounding per addition (not ``sum``: Python 3.12's
        total += x  # compensated float sum would round differently from the path above)
    return h * (total - 0.5 * (f[0] + f[-1])) / map_gain_rad_per_m(p)


def _terms(r: RenderState, p: ControlParams) -> list[tuple[float, float]]:
    """``(stiffness, contact angle)`` of every enabled finger, in finger order."""
    return [(k, c) for k, c, on in zip(r.stiffness_n_per_rad, r.contact_rad,
                                       p.finger_enable[:3], strict=True) if on]


def _force_of(terms: list[tuple[float, float]], how: str, f_max: float, theta: float) -> float:
    """``F_model`` at set-point ``theta`` from :func:`_terms`: the enabled fingers' forces
    combined as :func:`~teleop.control.transparency_layer.combine` does (same operations in
    the same order, so the same float), clipped at ``f_max``."""
    if not terms:
        return min(0.0, f_max)
    per = [k * max(theta - c, 0.0) for k, c in terms]
    if how == "max":
        x = max(per)
    elif how == "sum":
        x = sum(per)
    else:
        x = sum(per) / len(per)
    return min(max(x, 0.0), f_max)


def _force_at(r: RenderState, p: ControlParams, theta: float) -> float:
    """``F_model`` with every enabled finger at set-point ``theta``, clipped at the trigger's
    largest force."""
    on = p.finger_enable
    if on[0] and on[1] and on[2] and p.force_combine == "max":
        # the default (:func:`_force_of` over three terms) written out: ``max(a, b)`` as the
        # comparison it makes (``b if b > a else a``), so the same floats, signed zeros too
        (k0, k1, k2), (c0, c1, c2) = r.stiffness_n_per_rad, r.contact_rad
        d = theta - c0
        x = k0 * (0.0 if d < 0.0 else d)
        d = theta - c1
        x1 = k1 * (0.0 if d < 0.0 else d)
        d = theta - c2
        x2 = k2 * (0.0 if d < 0.0 else d)
        if x1 > x:
            x = x1
        if x2 > x:
            x = x2
        if x < 0.0:
            x = 0.0
        f_max = p.force_max_n
        return f_max if f_max < x else x
    return _force_of(_terms(r, p), p.force_combine, p.force_max_n, theta)


def damping_n_s_per_m(r: RenderState, p: ControlParams, periods: float, dt_s: float) -> float:
    """``b = periods * K * dt``, ``K`` the stiffest finger's rendered stiffness in N/m."""
    return periods * max(r.stiffness_n_per_rad) * map_gain_rad_per_m(p) * dt_s


def _mix(r: RenderState, c_t: Triple, k_t: Triple, a: float) -> RenderState:
    c = tuple(ci + a * (ct - ci) for ci, ct in zip(r.contact_rad, c_t, strict=True))
    k = tuple(ki + a * (kt - ki) for ki, kt in zip(r.stiffness_n_per_rad, k_t, strict=True))
    return RenderState(contact_rad=c, stiffness_n_per_rad=k)  # type: ignore[arg-type]


def step_render(r: RenderState, p: ControlParams, model: tuple[float, ...], q_m: float,
                budget_j: float, rate_n_per_s: float, dt_s: float,
                cut: bool = False, drop_rate_n_per_s: float | None = None) -> RenderState:
    """Move the rendered model towards ``model`` (wire form, see module docstring); ``cut``:
    the link is cut (a watchdog zeroed the command), a withdrawn model goes at once;
    ``drop_rate_n_per_s``: the rate limit of an update that lowers the force (None: the
    same as ``rate_n_per_s``)."""
    # (the per-finger expressions written out for the three fingers: same operations)
    k_t = (max(model[1], 0.0), max(model[3], 0.0), max(model[5], 0.0))
    k0, k1, k2 = k_t
    rc0, rc1, rc2 = r.contact_rad
    rk0, rk1, rk2 = r.stiffness_n_per_rad
    # a finger with no received model keeps its contact angle while its stiffness ramps out
    c_t = (model[0] if k0 > 0.0 else rc0, model[2] if k1 > 0.0 else rc1,
           model[4] if k2 > 0.0 else rc2)
    # a finger rendering nothing takes the new contact angle at once; with the link cut a
    # withdrawn model goes at once
    c_r = (c_t[0] if rk0 == 0.0 else rc0, c_t[1] if rk1 == 0.0 else rc1,
           c_t[2] if rk2 == 0.0 else rc2)
    k_r = ((0.0 if k0 == 0.0 else rk0, 0.0 if k1 == 0.0 else rk1,
            0.0 if k2 == 0.0 else rk2) if cut else (rk0, rk1, rk2))
    total = sum(k_t)
    if k_r == k_t and c_r == c_t:  # nothing to phase in
        return RenderState(contact_rad=c_r, stiffness_n_per_rad=k_r,
                           phase=1.0 if total > 0.0 else 0.0)
    r0 = RenderState(contact_rad=c_r, stiffness_n_per_rad=k_r)
    f0, e0 = model_force_n(r0, p, q_m), model_energy_j(r0, p, q_m)
    full = _mix(r0, c_t, k_t, 1.0)  # type: ignore[arg-type]
    up = rate_n_per_s * dt_s  # the most a sample may raise the force, and lower it
    down = up if drop_rate_n_per_s is None else drop_rate_n_per_s * dt_s
    jump = model_force_n(full, p, q_m) - f0
    a0 = min(1.0, (down if jump < 0.0 else up) / abs(jump)) if jump != 0.0 else 1.0
    new = r0
    for a in _ALPHAS:
        cand = _mix(r0, c_t, k_t, a * a0)  # type: ignore[arg-type]
        change = model_force_n(cand, p, q_m) - f0
        if not -down * (1.0 + 1e-9) <= change <= up * (1.0 + 1e-9):
            continue  # (the energy only for a candidate the rate limit lets through)
        e = model_energy_j(cand, p, q_m)
        if e <= budget_j or e <= e0:
            new = cand
            break
    phase = min(sum(new.stiffness_n_per_rad) / total, 1.0) if total > 0.0 else 0.0
    return RenderState(contact_rad=new.contact_rad, stiffness_n_per_rad=new.stiffness_n_per_rad,
                       phase=phase)
