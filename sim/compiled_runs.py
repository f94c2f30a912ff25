"""Compiled loops over the compiled finger step (:mod:`sim.compiled_step`).

Python calling the step once per millisecond pays the interpreter on every call; these loops
run many steps per call: a finger under a command sequence (the experiments, the diagnosis),
the whole hand between two reads (``SimHand``, with the energy audit of ``sim.audit``), and
the benchmark's 1 kHz controller (``teleop bench sim``).  Same arithmetic as the Python
reference, in the same order.

Numba's disk cache keys each function on its own file only, not on the kernels it
inlines; :mod:`sim.compiled_cache` drops the cache of every compiled module when any of
their sources changes, so an edit of the step or of the array layouts recompiles this
file's functions too.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sim.compiled_crush import pad_dent, yield_pad_work
from sim.compiled_kernel import (
    K_LD,
    K_PADSTART,
    K_PO,
    K_PROX,
    K_SEG,
    KIND_BLOCK,
    X_CRUSH,
    X_FLEX,
    X_PHI,
    block_core,
    mean_spring_force,
    pad_contact,
)
from sim.compiled_step import advance_in, work_array


@njit(cache=True)
def run_finger(x: np.ndarray, cmds: np.ndarray, dts: np.ndarray, k: np.ndarray,
               dsegs: np.ndarray, o: np.ndarray, e: np.ndarray, fixed_tension_n: float,
               record: np.ndarray, out: np.ndarray) -> int:
    """Step ``x`` in place under ``cmds[s]`` for ``dts[s]``; copy ``x`` into the next row of
    ``out`` before step ``s`` where ``record[s]`` (``record`` has one more entry: the end).
    Returns the number of rows written."""
    r = 0
    work = work_array(k)
    for s in range(cmds.shape[0]):
        if record[s]:
            out[r, :] = x
            r += 1
        advance_in(x, cmds[s], k, dsegs, o, e, dts[s], fixed_tension_n, work)
    if record[cmds.shape[0]]:
        out[r, :] = x
        r += 1
    return r


@njit(cache=True)
def squared_depth_integral(a: float, b: float) -> float:
    """``sim.audit.squared_depth_integral``."""
    if a > 0.0 and b > 0.0:
        return (a * a + a * b + b * b) / 3.0
    if b > 0.0:
        return b * b * b / (3.0 * (b - a))
    if a > 0.0:
        return a * a * a / (3.0 * (a - b))
    return 0.0


@njit(cache=True)
def bed_energy(o: np.ndarray, cphi: float, sphi: float, ax: float, ay: float, bx: float,
               by: float) -> float:
    """``sim.audit.bed_energy_j`` over the object array."""
    pa = sphi * ax + cphi * ay - o[2]
    pb = sphi * bx + cphi * by - o[2]
    dc = o[6]
    return 0.5 * (o[4] * squared_depth_integral(pa, pb)
                  + o[7] * squared_depth_integral(pa - dc, pb - dc))


@njit(cache=True)
def pad_depths(x: np.ndarray, k: np.ndarray, o: np.ndarray
               ) -> tuple[float, float, float, float, float, float, float, float, float, float,
                          float, float]:
    """``sim.audit.pad_depths`` over the arrays."""
    if o[0] == 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    phi = x[X_PHI]
    cphi = math.cos(phi)
    sphi = math.sin(phi)
    po = k[K_PO]
    s_p, d_p, _, _, _ = pad_contact(o, cphi, sphi, k[K_PADSTART], po, k[K_PROX], po)
    n = (x.shape[0] - X_FLEX) // 2
    px = k[K_PROX]
    py = 0.0
    a = 0.0
    for i in range(n):
        a += x[X_FLEX + i]
        px += k[K_SEG] * math.cos(a)
        py += k[K_SEG] * math.sin(a)
    ca = math.cos(a)
    sa = math.sin(a)
    ax = px - sa * po
    ay = py + ca * po
    bx = ax + ca * k[K_LD]
    by = ay + sa * k[K_LD]
    s_d, d_d, _, _, _ = pad_contact(o, cphi, sphi, ax, ay, bx, by)
    d_p = max(d_p, 0.0)
    d_d = max(d_d, 0.0)
    cs_p = 0.0
    cd_p = 0.0
    cs_d = 0.0
    cd_d = 0.0
    if o[0] == KIND_BLOCK:
        cs_p, cd_p, _ = block_core(o, cphi, sphi, k[K_PADSTART], po, k[K_PROX], po)
        cs_d, cd_d, _ = block_core(o, cphi, sphi, ax, ay, bx, by)
    if o[8] > 0.0:
        return (s_p, d_p, s_d, d_d, pad_dent(o, x[X_CRUSH], d_p),
                pad_dent(o, x[X_CRUSH + 1], d_d), cs_p, cd_p, cs_d, cd_d, 0.0, 0.0)
    e_p = 0.0
    e_d = 0.0
    if o[0] == KIND_BLOCK:
        e_p = bed_energy(o, cphi, sphi, k[K_PADSTART], po, k[K_PROX], po)
        e_d = bed_energy(o, cphi, sphi, ax, ay, bx, by)
    return s_p, d_p, s_d, d_d, 0.0, 0.0, cs_p, cd_p, cs_d, cd_d, e_p, e_d


@njit(cache=True)
def _pad_work(s0: float, d0: float, s1: float, d1: float, o: np.ndarray, dt: float,
              core: bool) -> float:
    if d0 <= 0.0 and d1 <= 0.0:
        return 0.0
    cc = o[5]
    dd = d1 - d0
    elastic = mean_spring_force(o, s0, d0, s1, d1, core)
    damping = cc * 0.5 * (s0 + s1) * dd / dt if dt > 0.0 else 0.0
    force = max(elastic + damping, 0.0)
    return force * dd


@njit(cache=True)
def bed_work(s0: float, d0: float, cs0: float, cd0: float, e0: float, s1: float, d1: float,
             cs1: float, cd1: float, e1: float, o: np.ndarray, dt: float) -> float:
    """``sim.audit._bed_work`` of one pad over the object array."""
    if d0 <= 0.0 and d1 <= 0.0:
        return 0.0
    dd = d1 - d0
    elastic = (mean_spring_force(o, s0, d0, s1, d1, False)
               + o[7] * 0.5 * (cs0 * cd0 + cs1 * cd1))
    damping = o[5] * 0.5 * (s0 + s1) * dd / dt if dt > 0.0 else 0.0
    if elastic + damping <= 0.0:
        return 0.0
    return (e1 - e0) + damping * dd


@njit(cache=True)
def core_work(s0: float, d0: float, s1: float, d1: float, o: np.ndarray) -> float:
    """``sim.audit.core_work_j`` over the object array."""
    if d0 <= 0.0 and d1 <= 0.0:
        return 0.0
    kc = o[7]
    return kc * 0.5 * (s0 * d0 + s1 * d1) * (d1 - d0)


@njit(cache=True)
def preshape_step(angle: float, vel: float, goal: float, hp: np.ndarray,
                  dt: float) -> tuple[float, float]:
    """``sim.hand.preshape_step``; ``hp`` = (inertia, kp, damping, max torque, lo, hi)."""
    m, kp, c, tmax, lo, hi = hp[0], hp[1], hp[2], hp[3], hp[4], hp[5]
    goal = min(max(goal, lo), hi)
    torque = kp * (goal - angle)
    if abs(torque) < tmax:
        vel = (m * vel + dt * torque) / (m + dt * c + dt * dt * kp)
    else:
        torque = tmax if torque > 0 else -tmax
        vel = (m * vel + dt * torque) / (m + dt * c)
    angle += dt * vel
    if angle < lo:
        angle, vel = lo, max(vel, 0.0)
    elif angle > hi:
        angle, vel = hi, min(vel, 0.0)
    return angle, vel


@njit(cache=True)
def run_hand(xs: np.ndarray, cs: np.ndarray, pre: np.ndarray, pre_goal: float, hp: np.ndarray,
             k: np.ndarray, dsegs: np.ndarray, objs: np.ndarray, e: np.ndarray, dt: float,
             steps: int, t_end: float, audit: bool, delivered: np.ndarray,
             taken: np.ndarray) -> int:
    """Up to ``steps`` of ``sim.hand.hand_step`` in place, stopping before a step once
    ``time + dt / 2 > t_end`` (``xs`` one row a finger, ``pre`` = [time, preshape angle,
    speed]); with ``audit`` the work on the object is added to ``delivered``/``taken`` per
    finger at every step, as ``SimHand.read`` does.  Returns the steps taken."""
    nf = xs.shape[0]
    depths = np.zeros((nf, 12))
    if audit:
        for i in range(nf):
            b = depths[i]
            (b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7], b[8], b[9], b[10],
             b[11]) = pad_depths(xs[i], k, objs[i])
    done = 0
    work = work_array(k)
    for _ in range(steps):
        if pre[0] + 0.5 * dt > t_end:
            break
        done += 1
        for i in range(nf):
            advance_in(xs[i], cs[i], k, dsegs, objs[i], e, dt, -1.0, work)
        pre[1], pre[2] = preshape_step(pre[1], pre[2], pre_goal, hp, dt)
        pre[0] = pre[0] + dt
        if audit:
            for i in range(nf):
                o = objs[i]
                (s_p, d_p, s_d, d_d, c_p, c_d, cs_p, cd_p, cs_d, cd_d, e_p,
                 e_d) = pad_depths(xs[i], k, o)
                b = depths[i]
                core = o[0] != KIND_BLOCK
                if o[8] > 0.0:
                    w = (yield_pad_work(b[0], b[1], b[4], s_p, d_p, c_p, o, dt, core)
                         + yield_pad_work(b[2], b[3], b[5], s_d, d_d, c_d, o, dt, core))
                    if not core:
                        w = (w + core_work(b[6], b[7], cs_p, cd_p, o)
                             + core_work(b[8], b[9], cs_d, cd_d, o))
                elif not core:  # an elastic block: its bed of springs' energy
                    w = (bed_work(b[0], b[1], b[6], b[7], b[10], s_p, d_p, cs_p, cd_p, e_p, o,
                                  dt)
                         + bed_work(b[2], b[3], b[8], b[9], b[11], s_d, d_d, cs_d, cd_d, e_d,
                                    o, dt))
                else:
                    w = (_pad_work(b[0], b[1], s_p, d_p, o, dt, core)
                         + _pad_work(b[2], b[3], s_d, d_d, o, dt, core))
                b[0], b[1], b[2], b[3], b[4], b[5] = s_p, d_p, s_d, d_d, c_p, c_d
                b[6], b[7], b[8], b[9], b[10], b[11] = cs_p, cd_p, cs_d, cd_d, e_p, e_d
                if w > 0.0:
                    delivered[i] += w
                else:
                    taken[i] -= w
    return done
