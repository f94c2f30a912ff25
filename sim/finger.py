"""One ReFlex TakkTile finger, its tendon and its MX-28 motor: a physical simulation.

API summary (the shared contract; other modules use exactly these names)::

    params = default_finger_params()                  # FingerParams (sim/params.py)
    state = initial_finger_state(params)              # FingerState, finger open, tendon slack
    cmd = MotorCommand("position", goal_rad=1.0)      # shaft angle; joint angle = shaft / 1.42
    obj = contact_object_from_config(cfg.hand.sim.object)   # or ContactObject(kind="none")
    state = finger_step(state, cmd, params, obj, EffectSet(), dt_s=1e-3)   # pure
    out = finger_outputs(state, params, obj, EffectSet())                  # FingerOutputs
    out.proximal_rad, out.distal_rad, out.motor_angle_rad, out.motor_velocity_rad_s,
    out.tendon_force_n, out.motor_load_units, out.pressure (9), out.contact (9), out.points

    weight_equilibrium(params, force_n) -> (proximal_rad, distal_rad)   # Table 4.2 test

Modules: constants in ``sim/params.py``, the state in ``sim/state.py``, measurements in
``sim/readout.py``, contact and pressures in ``sim/contact.py``, the servo's effort effects and
friction in ``sim/motor.py``; this module holds the step and re-exports the API.

Model (report chapter 4 / appendix B):

* generalised coordinates: proximal angle on the base joint (torsional spring with a preload
  against the open stop, so the finger rests at 0), ``n_flex`` flexure segment angles (the
  urethane joint as torsional spring-dampers in series), motor shaft angle;
* the tendon runs from the spool over the base (moment arm ``r_base_m``), pin X1 (proximal),
  pin X2 (distal) to the tip anchor Xc; its length is eq. 4.4,
  ``l_s = -r_b phi + l_12(flexure) + const``, its speed ``v_s = -r_b phi' + l_12'``.  The
  tendon is a stiff one-way spring (it only pulls).  Its generalised forces are the virtual work
  of the pseudo-transformer forces ``F = 2 F_s cos(theta)`` at X1, X2 and ``F_s`` at Xc
  (:func:`finger_outputs` reports those forces for drawing);
* the mass matrix is approximated by a constant diagonal (light links, dynamics dominated by the
  motor friction and the springs); each coordinate's springs, dampers, contact and the tendon
  are integrated linearly implicitly (backward Euler, the tendon tension solved in closed form
  as a rank-one coupling), so the stiff flexure and tendon are stable at 1 ms steps;
* joint limits are inelastic stops.

Effects (``teleop.effects.EffectSet``; forces in N of tendon force, positions in rad of motor
shaft or joint angle): dead_time delays the command; coulomb/asymmetric friction and stiction
act in the motor; backlash is a dead band between the motor shaft and the spool; actuator
saturation/gain/lag act on the motor effort; sensor_offset is added to the measured motor and
proximal angles (the servo controls on its measured angle); series_compliance is a spring in
series with the tendon (N per rad of shaft angle); nonlinear_stiffness is a cubic base spring
(N of tendon force per rad^3 of proximal angle, times r_base); gravity a moment
``-g r_base sin(phi)`` on the base joint.
"""

from __future__ import annotations

import math
from typing import Any

from sim.contact import ContactObject, contact_object_from_config, pad_contact
from sim.crush import pad_force
from sim.motor import HOLD_ZERO, MotorCommand, apply_effort_effects, friction_force_n
from sim.params import (
    JOINT_RATIO,
    FingerParams,
    default_finger_params,
    speed_friction_at,
    speed_law_pieces,
)
from sim.readout import FingerOutputs, finger_energy_j, finger_outputs, tendon_stretch_m
from sim.state import FingerState, initial_finger_state
from teleop.effects import EffectSet

__all__ = [
    "ContactObject", "FingerOutputs", "FingerParams", "FingerState", "MotorCommand",
    "contact_object_from_config", "default_finger_params", "finger_outputs", "finger_step",
    "initial_finger_state", "weight_equilibrium", "JOINT_RATIO", "NO_EFFECTS",
    "finger_energy_j", "hung_weight_step", "tendon_stretch_m",
]

NO_EFFECTS = EffectSet()
_PROX_PAD_START_M = 0.010


_CONSTS: dict[int, tuple[FingerParams, tuple[Any, ...]]] = {}


def _damping_segments(p: FingerParams) -> tuple[tuple[float, float, float, float], ...]:
    """(upper input bound, u0, d0, exponent) of the log-log pieces of the damping law."""
    tab = p.damping_table
    segs = []
    for i in range(1, len(tab)):
        (u0, d0), (u1, d1) = tab[i - 1], tab[i]
        upper = u1 if i < len(tab) - 1 else math.inf
        segs.append((upper, u0, d0, math.log(d1 / d0) / math.log(u1 / u0)))
    return tuple(segs)


def _consts(p: FingerParams) -> tuple[Any, ...]:
    """Per-params derived constants, cached (the step is hot)."""
    hit = _CONSTS.get(id(p))
    if hit is not None and hit[0] is p:
        return hit[1]
    n = p.n_flex
    p1x, p1y = p.pin1_xy_m
    p2x, p2y = p.pin2_xy_m
    l12_0 = math.hypot(p.proximal_rigid_m + n * p.flex_segment_m + p2x - p1x, p2y - p1y)
    out = (l12_0, p.k_flex_total_nm_per_rad * n, p.units_per_n, p.r_motor_m, p.r_base_m,
           p.k_base_nm_per_rad, p.base_preload_rad, p.c_base_nm_s_per_rad,
           p.c_flex_segment_nm_s_per_rad, p.inertia_proximal_kg_m2, p.inertia_flex_kg_m2,
           p.inertia_motor_kg_m2, p.k_tendon_n_per_m, p.c_tendon_n_s_per_m, p.tendon_slack_m,
           p.proximal_rigid_m, p.flex_segment_m, p1x, p1y, p2x, p2y, p.pad_offset_m,
           p.distal_length_m, p.proximal_limits_rad[0], p.proximal_limits_rad[1],
           p.flex_segment_limits_rad[0], p.flex_segment_limits_rad[1], _damping_segments(p),
           p.max_effort_units, p.kp_units_per_rad,
           p.motor_coulomb_units / p.units_per_n, p.coulomb_velocity_rad_s,
           p.speed_law_fraction,
           speed_law_pieces(p) if p.speed_law_fraction != 0.0 else (),
           p.shaft_ripple_sin_n, p.shaft_ripple_cos_n, p.shaft_ripple_per_rad)
    if len(_CONSTS) > 64:
        _CONSTS.clear()
    _CONSTS[id(p)] = (p, out)
    return out


def _step(state: FingerState, cmd: MotorCommand, p: FingerParams, obj: ContactObject,
          eff: EffectSet, dt: float, fixed_tension_n: float) -> FingerState:
    """One linearly implicit step; ``fixed_tension_n >= 0`` detaches the motor (hung weight)."""
    (l12_0, kseg, upn, rm, rb, kb, preload, c_phi, cseg, m_phi, m_fl, m_m, kt, ct, slack,
     prox_len, seg, p1x, p1y, p2x, p2y, po, ld, lo, hi, slo, shi, dsegs, umax, kp, fc0,
     vs, sfrac, spieces, rip_s, rip_c, rip_w) = _consts(p)
    t = state.t_s
    # --- command path: driver delay + dead_time effect -----------------------------------
    delay = p.command_delay_s + eff.dead_time
    active, last, pending = state.command
    gap, ref, effort_prev, _ = state.drive
    if delay <= 0.0:
        active = cmd
    else:
        if cmd is not last and cmd != last:
            pending = (*pending, (t + delay, cmd))
        while pending and pending[0][0] <= t + 1e-12:
            active = pending[0][1]
            pending = pending[1:]
    # --- servo -------------------------------------------------------------------------
    th_m = state.motor_rad
    v_m = state.motor_vel_rad_s
    # servo set-point (speed 0 = jump to the goal) and effort (units, + pulls the tendon)
    mode = active.mode
    goal = active.goal_rad
    speed = active.speed_rad_s
    if speed <= 0.0 or mode == "force":
        ref = goal
    else:
        step = speed * dt
        if goal - ref > step:
            ref += step
        elif goal - ref < -step:
            ref -= step
        else:
            ref = goal
    tl = active.torque_limit
    limit = umax * (0.0 if tl < 0.0 else (1.0 if tl > 1.0 else tl))
    u_cmd = active.force_units if mode == "force" else kp * (ref - th_m - eff.sensor_offset)
    if u_cmd > limit:
        u_cmd = limit
    elif u_cmd < -limit:
        u_cmd = -limit
    u = u_cmd
    if eff is not NO_EFFECTS:
        u = apply_effort_effects(u_cmd, effort_prev, eff, p, dt)
        ffric, fslope = friction_force_n(v_m, p, eff)
    else:  # regularised Coulomb friction (sim.motor.friction_force_n without effects)
        xv = v_m / vs
        if xv > 20.0:
            ffric, fslope = fc0, 0.0
        elif xv < -20.0:
            ffric, fslope = -fc0, 0.0
        else:
            th = math.tanh(xv)
            ffric, fslope = fc0 * th, fc0 * (1.0 - th * th) / vs
    # viscous friction falling with the input (Table 4.1; sim.params.motor_damping_units)
    ua = -u if u < 0.0 else u
    ua = 20.0 if ua < 20.0 else (umax if ua > umax else ua)
    piece = dsegs[-1]
    for cand in dsegs:
        if ua <= cand[0]:
            piece = cand
            break
    _, u0, d0, expo = piece
    if sfrac == 0.0:
        c_m = d0 * (ua / u0) ** expo / upn * rm + fslope * rm
        f_m = u / upn * rm - ffric * rm + fslope * rm * v_m
    else:  # blended with the speed law (sim.params.speed_friction_units), linearised at v_m
        g_v, g_slope = speed_friction_at(v_m, spieces)
        c_m = ((1.0 - sfrac) * d0 * (ua / u0) ** expo + sfrac * g_slope) / upn * rm \
            + fslope * rm
        f_m = u / upn * rm - ffric * rm + fslope * rm * v_m \
            - sfrac * (g_v - g_slope * v_m) / upn * rm
    if rip_w != 0.0:  # position-periodic shaft force, explicit in the angle
        f_m -= (rip_s * math.sin(rip_w * th_m) + rip_c * math.cos(rip_w * th_m)) * rm
    # --- finger geometry (proximal frame) ------------------------------------------------
    phi = state.prox_rad
    v_phi = state.prox_vel_rad_s
    flex = state.flex_rad
    fvel = state.flex_vel_rad_s
    n = len(flex)
    jx = [0.0] * n
    jy = [0.0] * n
    x = prox_len
    y = 0.0
    a = 0.0
    ca = 1.0
    sa = 0.0
    for i in range(n):
        jx[i] = x
        jy[i] = y
        a += flex[i]
        ca = math.cos(a)
        sa = math.sin(a)
        x += seg * ca
        y += seg * sa
    x2 = x + ca * p2x - sa * p2y
    y2 = y + sa * p2x + ca * p2y
    dx = x2 - p1x
    dy = y2 - p1y
    l12 = math.sqrt(dx * dx + dy * dy)
    ux = dx / l12
    uy = dy / l12
    # --- springs, gravity, nonlinear stiffness ---------------------------------------------
    f_phi = -kb * (phi + preload)
    k_phi = kb
    if eff is not NO_EFFECTS:
        if eff.gravity != 0.0:
            f_phi -= eff.gravity * rb * math.sin(phi)
            k_phi += max(0.0, eff.gravity * rb * math.cos(phi))
        if eff.nonlinear_stiffness != 0.0:
            f_phi -= eff.nonlinear_stiffness * rb * phi * phi * phi
            k_phi += max(0.0, 3.0 * eff.nonlinear_stiffness * rb * phi * phi)
    jns: list[float] | None = None  # distal contact Jacobian (normal) per flexure segment
    fk = ke = ce = vn = 0.0
    # --- contact on the pads -------------------------------------------------------------
    pc_n = pc_x = dc_n = dc_x = 0.0
    crush = state.crush_m
    if obj.kind != "none":
        cphi = math.cos(phi)
        sphi = math.sin(phi)
        crush_p, crush_d = crush
        ax0 = _PROX_PAD_START_M
        scale, depth, tt, nx, ny = pad_contact(obj, cphi, sphi, ax0, po, prox_len, po)
        if depth > 0.0:
            fe, ke, ce, tt, crush_p = pad_force(obj, cphi, sphi, ax0, po, prox_len, po, scale,
                                                depth, tt, crush_p)
            px = ax0 + tt * (prox_len - ax0)
            jn = -po * nx + px * ny
            force = fe - ce * jn * v_phi
            if force > 0.0:
                f_phi += fe * jn
                k_phi += ke * jn * jn
                c_phi += ce * jn * jn
                pc_n = force
                pc_x = px
        axd = x - sa * po
        ayd = y + ca * po
        bxd = axd + ca * ld
        byd = ayd + sa * ld
        scale, depth, tt, nx, ny = pad_contact(obj, cphi, sphi, axd, ayd, bxd, byd)
        if depth > 0.0:
            fe, ke, ce, tt, crush_d = pad_force(obj, cphi, sphi, axd, ayd, bxd, byd, scale,
                                                depth, tt, crush_d)
            px = axd + tt * (bxd - axd)
            py = ayd + tt * (byd - ayd)
            jn_phi = -py * nx + px * ny
            jl = [-(py - jy[i]) * nx + (px - jx[i]) * ny for i in range(n)]
            vn = jn_phi * v_phi
            for i in range(n):
                vn += jl[i] * fvel[i]
            force = fe - ce * vn
            if force > 0.0:
                fk = fe
                f_phi += fk * jn_phi - ce * jn_phi * (vn - jn_phi * v_phi)
                k_phi += ke * jn_phi * jn_phi
                c_phi += ce * jn_phi * jn_phi
                jns = jl
                dc_n = force
                dc_x = tt * ld
        crush = (crush_p, crush_d)
    # --- linearly implicit velocities with the tendon tension solved in closed form -------
    # generalised tendon force per newton of tension: r_b on phi, g_i = -dl12/ds_i on s_i,
    # -r_m on the motor
    dt2 = dt * dt
    d_phi = m_phi + dt * c_phi + dt2 * k_phi
    a_phi = (m_phi * v_phi + dt * f_phi) / d_phi
    d_m = m_m + dt * c_m
    a_m = (m_m * v_m + dt * f_m) / d_m
    big_a = -rb * a_phi + rm * a_m
    big_b = dt * (rb * rb / d_phi + rm * rm / d_m)
    b_fl = [0.0] * n
    a_fl = [0.0] * n
    d_free = m_fl + dt * cseg + dt2 * kseg
    for i in range(n):
        gi = ux * (y2 - jy[i]) - uy * (x2 - jx[i])
        vi = fvel[i]
        fi = -kseg * flex[i]
        if jns is None:
            di = d_free
        else:  # distal pad contact: its spring implicit, its damping implicit on the diagonal
            ji = jns[i]
            fi += fk * ji - ce * ji * (vn - ji * vi)
            di = d_free + (dt * ce + dt2 * ke) * ji * ji
        ai = (m_fl * vi + dt * fi) / di
        bi = dt * gi / di
        a_fl[i] = ai
        b_fl[i] = bi
        big_a -= gi * ai
        big_b += gi * bi
    width = eff.backlash
    spool = th_m - gap
    stretch_base = (l12 - l12_0) - rb * phi - slack
    if eff.series_compliance != math.inf:
        k_series = eff.series_compliance / rm
        k_new = 1.0 / (1.0 / kt + 1.0 / k_series)
        ct *= k_new / kt
        kt = k_new
    engaged = True
    if fixed_tension_n >= 0.0:
        tension = fixed_tension_n
        engaged = False
    else:
        if width > 0.0:
            spool_eng = th_m - 0.5 * width
            engaged = rm * spool_eng + stretch_base > 0.0
            if engaged:
                spool = spool_eng
        if engaged:
            e = rm * spool + stretch_base
            kk = kt * dt + ct
            tension = (kt * e + kk * big_a) / (1.0 + kk * big_b)
            if tension < 0.0:
                tension = 0.0
        else:
            tension = 0.0
    v_phi_n = a_phi + dt * rb * tension / d_phi
    v_m_n = a_m - dt * rm * tension / d_m if engaged else a_m
    # --- positions and stops -----------------------------------------------------------
    phi_n = phi + dt * v_phi_n
    if phi_n <= lo:
        phi_n = lo
        if v_phi_n < 0.0:
            v_phi_n = 0.0
    elif phi_n >= hi:
        phi_n = hi
        if v_phi_n > 0.0:
            v_phi_n = 0.0
    flex_n = [0.0] * n
    for i in range(n):
        vi = a_fl[i] + b_fl[i] * tension
        s = flex[i] + dt * vi
        if s <= slo:
            s = slo
            if vi < 0.0:
                vi = 0.0
        elif s >= shi:
            s = shi
            if vi > 0.0:
                vi = 0.0
        flex_n[i] = s
        a_fl[i] = vi
    th_m_n = th_m + dt * v_m_n
    if width > 0.0:
        if engaged and fixed_tension_n < 0.0:
            gap_n = 0.5 * width
        else:
            sp = min(max(spool, th_m_n - 0.5 * width), th_m_n + 0.5 * width)
            gap_n = th_m_n - sp
    else:
        gap_n = 0.0
    return FingerState(t + dt, phi_n, v_phi_n, tuple(flex_n), tuple(a_fl), th_m_n, v_m_n,
                       tension, (gap_n, ref, u, u_cmd), (pc_n, pc_x, dc_n, dc_x),
                       (active, cmd, pending), crush)


def finger_step(state: FingerState, cmd: MotorCommand, params: FingerParams,
                obj: ContactObject, effects: EffectSet, dt_s: float) -> FingerState:
    """Advance the finger by ``dt_s`` under motor command ``cmd`` (pure)."""
    return _step(state, cmd, params, obj, effects, dt_s, -1.0)


def hung_weight_step(state: FingerState, params: FingerParams, force_n: float,
                     dt_s: float, effects: EffectSet = NO_EFFECTS) -> FingerState:
    """Advance the finger detached from the motor with ``force_n`` hung on the tendon."""
    return _step(state, HOLD_ZERO, params, ContactObject(), effects, dt_s, max(force_n, 0.0))


def weight_equilibrium(params: FingerParams, force_n: float, *, dt_s: float = 1e-3,
                       max_time_s: float = 30.0, effects: EffectSet = NO_EFFECTS,
                       engine_name: str | None = None) -> tuple[float, float]:
    """Static equilibrium (proximal, distal rad) under a weight on the detached tendon.

    Found physically: the finger is released from rest and its damped dynamics run until it is
    still (speeds below 1e-6 rad/s), as the report's weight test (Table 4.2) did.  The run is
    the compiled engine's (``sim.compiled_weight``) unless ``engine_name`` is ``"python"``.
    """
    from sim.engine import DEFAULT_ENGINE, engine

    if engine(engine_name or DEFAULT_ENGINE).name == "compiled":
        from sim.compiled_weight import compiled_weight_equilibrium

        return compiled_weight_equilibrium(params, force_n, dt_s, max_time_s, effects)
    state = initial_finger_state(params)
    steps = int(max_time_s / dt_s)
    for k in range(steps):
        state = hung_weight_step(state, params, force_n, dt_s, effects)
        if k > 100 and abs(state.prox_vel_rad_s) < 1e-6 and all(
                abs(v) < 1e-6 for v in state.flex_vel_rad_s):
            break
    return state.prox_rad, sum(state.flex_rad)
