"""The compiled finger step: ``sim.finger._step`` over the arrays of :mod:`sim.compiled_kernel`.

Line for line the Python reference (same operations in the same order, no fast-math); the
delay line of commands stays in Python (:mod:`sim.compiled`), the step gets the command in
force.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sim.compiled_crush import pad_force
from sim.compiled_kernel import (
    E_BACKLASH,
    E_GRAVITY,
    E_NONLIN,
    E_SERIES,
    K_CPHI,
    K_CSEG,
    K_CT,
    K_HI,
    K_KB,
    K_KSEG,
    K_KT,
    K_L12_0,
    K_LD,
    K_LO,
    K_MFL,
    K_MM,
    K_MPHI,
    K_N,
    K_P1X,
    K_P1Y,
    K_P2X,
    K_P2Y,
    K_PADSTART,
    K_PO,
    K_PRELOAD,
    K_PROX,
    K_RB,
    K_RIP_C,
    K_RIP_S,
    K_RIP_W,
    K_RM,
    K_SEG,
    K_SFRAC,
    K_SHI,
    K_SLACK,
    K_SLO,
    K_UMAX,
    K_UPN,
    KIND_NONE,
    X_CRUSH,
    X_FLEX,
    X_GAP,
    X_PADS,
    X_PHI,
    X_REF,
    X_T,
    X_TEN,
    X_TH,
    X_U,
    X_UCMD,
    X_VM,
    X_VPHI,
    motor_effort,
    motor_friction,
    pad_contact,
    speed_friction,
)


@njit(cache=True)
def work_array(k: np.ndarray) -> np.ndarray:
    """The per-segment work arrays :func:`advance_in` writes before it reads them, for the
    finger packed in ``k``: allocated once per run, not once per step."""
    return np.empty((5, int(k[K_N])))


@njit(cache=True)
def advance(x: np.ndarray, c: np.ndarray, k: np.ndarray, dsegs: np.ndarray, o: np.ndarray,
            e: np.ndarray, dt: float, fixed_tension_n: float) -> None:
    """One linearly implicit step of ``sim.finger._step``, in place on ``x`` (a loop of steps
    calls :func:`advance_in` with one :func:`work_array`: five allocations a step less)."""
    advance_in(x, c, k, dsegs, o, e, dt, fixed_tension_n, work_array(k))


@njit(cache=True)
def advance_in(x: np.ndarray, c: np.ndarray, k: np.ndarray, dsegs: np.ndarray, o: np.ndarray,
               e: np.ndarray, dt: float, fixed_tension_n: float, w: np.ndarray) -> None:
    """:func:`advance` with ``w`` (:func:`work_array`) for the per-segment arrays it writes
    before it reads them."""
    n = int(k[K_N])
    rm = k[K_RM]
    rb = k[K_RB]
    umax = k[K_UMAX]
    upn = k[K_UPN]
    th_m = x[X_TH]
    v_m = x[X_VM]
    ref, u, u_cmd = motor_effort(x, c, k, e, dt)
    ffric, fslope = motor_friction(v_m, k, e)
    ua = -u if u < 0.0 else u
    ua = 20.0 if ua < 20.0 else (umax if ua > umax else ua)
    piece = dsegs.shape[0] - 1
    for j in range(dsegs.shape[0]):
        if ua <= dsegs[j, 0]:
            piece = j
            break
    u0 = dsegs[piece, 1]
    d0 = dsegs[piece, 2]
    expo = dsegs[piece, 3]
    sfrac = k[K_SFRAC]
    if sfrac == 0.0:
        c_m = d0 * (ua / u0) ** expo / upn * rm + fslope * rm
        f_m = u / upn * rm - ffric * rm + fslope * rm * v_m
    else:  # blended with the speed law, linearised at v_m
        g_v, g_slope = speed_friction(v_m, k)
        c_m = ((1.0 - sfrac) * d0 * (ua / u0) ** expo + sfrac * g_slope) / upn * rm \
            + fslope * rm
        f_m = u / upn * rm - ffric * rm + fslope * rm * v_m \
            - sfrac * (g_v - g_slope * v_m) / upn * rm
    if k[K_RIP_W] != 0.0:  # position-periodic shaft force, explicit in the angle
        f_m -= (k[K_RIP_S] * math.sin(k[K_RIP_W] * th_m)
                + k[K_RIP_C] * math.cos(k[K_RIP_W] * th_m)) * rm
    # finger geometry (proximal frame)
    phi = x[X_PHI]
    v_phi = x[X_VPHI]
    flex = x[X_FLEX:X_FLEX + n]
    fvel = x[X_FLEX + n:X_FLEX + 2 * n]
    jx = w[0]
    jy = w[1]
    px_ = k[K_PROX]
    py_ = 0.0
    a = 0.0
    ca = 1.0
    sa = 0.0
    for i in range(n):
        jx[i] = px_
        jy[i] = py_
        a += flex[i]
        ca = math.cos(a)
        sa = math.sin(a)
        px_ += k[K_SEG] * ca
        py_ += k[K_SEG] * sa
    x2 = px_ + ca * k[K_P2X] - sa * k[K_P2Y]
    y2 = py_ + sa * k[K_P2X] + ca * k[K_P2Y]
    dx = x2 - k[K_P1X]
    dy = y2 - k[K_P1Y]
    l12 = math.sqrt(dx * dx + dy * dy)
    ux = dx / l12
    uy = dy / l12
    # springs, gravity, nonlinear stiffness
    kb = k[K_KB]
    f_phi = -kb * (phi + k[K_PRELOAD])
    k_phi = kb
    c_phi = k[K_CPHI]
    if e[E_GRAVITY] != 0.0:
        f_phi -= e[E_GRAVITY] * rb * math.sin(phi)
        k_phi += max(0.0, e[E_GRAVITY] * rb * math.cos(phi))
    if e[E_NONLIN] != 0.0:
        f_phi -= e[E_NONLIN] * rb * phi * phi * phi
        k_phi += max(0.0, 3.0 * e[E_NONLIN] * rb * phi * phi)
    jns = w[2]
    jns[:] = 0.0
    distal_touch = False
    fk = 0.0
    ke = 0.0
    ce = 0.0
    vn = 0.0
    pc_n = 0.0
    pc_x = 0.0
    dc_n = 0.0
    dc_x = 0.0
    crush_p = x[X_CRUSH]
    crush_d = x[X_CRUSH + 1]
    if o[0] != KIND_NONE:
        cphi = math.cos(phi)
        sphi = math.sin(phi)
        po = k[K_PO]
        prox_len = k[K_PROX]
        ax0 = k[K_PADSTART]
        scale, depth, tt, nx, ny = pad_contact(o, cphi, sphi, ax0, po, prox_len, po)
        if depth > 0.0:
            fe, ke, ce, tt, crush_p = pad_force(o, cphi, sphi, ax0, po, prox_len, po, scale,
                                                depth, tt, crush_p)
            cx_ = ax0 + tt * (prox_len - ax0)
            jn = -po * nx + cx_ * ny
            force = fe - ce * jn * v_phi
            if force > 0.0:
                f_phi += fe * jn
                k_phi += ke * jn * jn
                c_phi += ce * jn * jn
                pc_n = force
                pc_x = cx_
        ld = k[K_LD]
        axd = px_ - sa * po
        ayd = py_ + ca * po
        bxd = axd + ca * ld
        byd = ayd + sa * ld
        scale, depth, tt, nx, ny = pad_contact(o, cphi, sphi, axd, ayd, bxd, byd)
        if depth > 0.0:
            fe, ke, ce, tt, crush_d = pad_force(o, cphi, sphi, axd, ayd, bxd, byd, scale,
                                                depth, tt, crush_d)
            cx_ = axd + tt * (bxd - axd)
            cy_ = ayd + tt * (byd - ayd)
            jn_phi = -cy_ * nx + cx_ * ny
            for i in range(n):
                jns[i] = -(cy_ - jy[i]) * nx + (cx_ - jx[i]) * ny
            vn = jn_phi * v_phi
            for i in range(n):
                vn += jns[i] * fvel[i]
            force = fe - ce * vn
            if force > 0.0:
                fk = fe
                f_phi += fk * jn_phi - ce * jn_phi * (vn - jn_phi * v_phi)
                k_phi += ke * jn_phi * jn_phi
                c_phi += ce * jn_phi * jn_phi
                distal_touch = True
                dc_n = force
                dc_x = tt * ld
    # linearly implicit velocities, the tendon tension in closed form
    m_phi = k[K_MPHI]
    m_m = k[K_MM]
    m_fl = k[K_MFL]
    kseg = k[K_KSEG]
    dt2 = dt * dt
    d_phi = m_phi + dt * c_phi + dt2 * k_phi
    a_phi = (m_phi * v_phi + dt * f_phi) / d_phi
    d_m = m_m + dt * c_m
    a_m = (m_m * v_m + dt * f_m) / d_m
    big_a = -rb * a_phi + rm * a_m
    big_b = dt * (rb * rb / d_phi + rm * rm / d_m)
    b_fl = w[3]
    a_fl = w[4]
    d_free = m_fl + dt * k[K_CSEG] + dt2 * kseg
    for i in range(n):
        gi = ux * (y2 - jy[i]) - uy * (x2 - jx[i])
        vi = fvel[i]
        fi = -kseg * flex[i]
        if not distal_touch:
            di = d_free
        else:
            ji = jns[i]
            fi += fk * ji - ce * ji * (vn - ji * vi)
            di = d_free + (dt * ce + dt2 * ke) * ji * ji
        ai = (m_fl * vi + dt * fi) / di
        bi = dt * gi / di
        a_fl[i] = ai
        b_fl[i] = bi
        big_a -= gi * ai
        big_b += gi * bi
    width = e[E_BACKLASH]
    gap = x[X_GAP]
    spool = th_m - gap
    stretch_base = (l12 - k[K_L12_0]) - rb * phi - k[K_SLACK]
    kt = k[K_KT]
    ct = k[K_CT]
    if e[E_SERIES] != math.inf:
        k_series = e[E_SERIES] / rm
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
            ee = rm * spool + stretch_base
            kk = kt * dt + ct
            tension = (kt * ee + kk * big_a) / (1.0 + kk * big_b)
            if tension < 0.0:
                tension = 0.0
        else:
            tension = 0.0
    v_phi_n = a_phi + dt * rb * tension / d_phi
    v_m_n = a_m - dt * rm * tension / d_m if engaged else a_m
    # positions and stops
    phi_n = phi + dt * v_phi_n
    if phi_n <= k[K_LO]:
        phi_n = k[K_LO]
        if v_phi_n < 0.0:
            v_phi_n = 0.0
    elif phi_n >= k[K_HI]:
        phi_n = k[K_HI]
        if v_phi_n > 0.0:
            v_phi_n = 0.0
    slo = k[K_SLO]
    shi = k[K_SHI]
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
        x[X_FLEX + i] = s
        x[X_FLEX + n + i] = vi
    th_m_n = th_m + dt * v_m_n
    if width > 0.0:
        if engaged and fixed_tension_n < 0.0:
            gap_n = 0.5 * width
        else:
            sp = min(max(spool, th_m_n - 0.5 * width), th_m_n + 0.5 * width)
            gap_n = th_m_n - sp
    else:
        gap_n = 0.0
    x[X_T] = x[X_T] + dt
    x[X_PHI] = phi_n
    x[X_VPHI] = v_phi_n
    x[X_TH] = th_m_n
    x[X_VM] = v_m_n
    x[X_TEN] = tension
    x[X_GAP] = gap_n
    x[X_REF] = ref
    x[X_U] = u
    x[X_UCMD] = u_cmd
    x[X_PADS] = pc_n
    x[X_PADS + 1] = pc_x
    x[X_PADS + 2] = dc_n
    x[X_PADS + 3] = dc_x
    x[X_CRUSH] = crush_p
    x[X_CRUSH + 1] = crush_d
