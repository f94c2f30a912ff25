"""The finger step of :mod:`sim.finger` compiled with numba, over flat float64 arrays.

The same arithmetic as ``sim.finger._step`` in the same order (no fast-math, so the compiled
step follows the Python reference to rounding; ``tests/sim/test_compiled_engine.py`` holds it
to 1e-9 rad).  The Python step stays the reference; :mod:`sim.compiled` packs the dataclasses
into the arrays below and back.

Layouts (indices are the ``X_*``, ``C_*``, ``K_*``, ``O_*``, ``E_*`` constants):

* state ``x`` (``X_FLEX + 2 n``): time, proximal angle and speed, motor angle and speed, tendon
  tension, drive (backlash gap, servo set-point, effort, asked effort), pads (proximal force,
  where, distal force, where), the dents of a yielding object under the proximal and the
  distal pad (``sim.crush``), then the ``n`` flexure angles and their ``n`` speeds;
* command ``c`` (5): mode (0 position, 1 force, 2 velocity), goal, speed, force units, torque
  limit (the command in force, after any delay: the delay line stays in Python);
* constants ``k`` (see :func:`sim.compiled.pack_params`) and the damping pieces ``dsegs``
  (rows of upper input bound, u0, d0, exponent);
* object ``o`` (10): kind (0 none, 1 cylinder, 2 block), x, y, radius, stiffness, damping, core
  depth, core stiffness, yield force, yield hardening;
* effects ``e`` (12): the fields of ``teleop.effects.EffectSet`` in their order.

Every function is ``@njit(cache=True)``: compiled once, then loaded from numba's disk cache
(``sim.compiled.warm_up`` does that before a real-time loop starts).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

X_T, X_PHI, X_VPHI, X_TH, X_VM, X_TEN = 0, 1, 2, 3, 4, 5
X_GAP, X_REF, X_U, X_UCMD = 6, 7, 8, 9
X_PADS = 10
X_CRUSH = 14
X_FLEX = 16
MODE_POSITION, MODE_FORCE, MODE_VELOCITY = 0.0, 1.0, 2.0
(K_L12_0, K_KSEG, K_UPN, K_RM, K_RB, K_KB, K_PRELOAD, K_CPHI, K_CSEG, K_MPHI, K_MFL, K_MM, K_KT,
 K_CT, K_SLACK, K_PROX, K_SEG, K_P1X, K_P1Y, K_P2X, K_P2Y, K_PO, K_LD, K_LO, K_HI, K_SLO, K_SHI,
 K_UMAX, K_KP, K_FC0, K_VS, K_N, K_PADSTART, K_SFRAC) = range(34)
K_SPIECES = 34  # the speed law's 3 pieces (lower speed, friction units, exponent), 9 numbers
K_RIP_S, K_RIP_C, K_RIP_W = 43, 44, 45  # the position-periodic shaft force (sin, cos, w)
N_K = 46
(E_DEAD, E_COULOMB, E_ASYM, E_STICTION, E_BACKLASH, E_SAT, E_GAIN, E_LAG, E_OFFSET, E_SERIES,
 E_NONLIN, E_GRAVITY) = range(12)
KIND_NONE, KIND_CYLINDER, KIND_BLOCK = 0.0, 1.0, 2.0


@njit(cache=True)
def pad_spring(o: np.ndarray, scale: float, depth: float,
               core: bool = True) -> tuple[float, float]:
    """``sim.contact.pad_spring`` over the object array."""
    ke = o[4] * scale
    force = ke * depth
    if core and depth > o[6]:
        kc = o[7] * scale
        force += kc * (depth - o[6])
        ke += kc
    return force, ke


@njit(cache=True)
def mean_spring_force(o: np.ndarray, s0: float, d0: float, s1: float, d1: float,
                      core: bool = True) -> float:
    """``sim.contact.mean_spring_force`` over the object array."""
    f0 = pad_spring(o, s0, d0, core)[0]
    f1 = pad_spring(o, s1, d1, core)[0]
    dc = o[6]
    if (d0 - dc) * (d1 - dc) >= 0.0:
        return 0.5 * (f0 + f1)
    a = (dc - d0) / (d1 - d0)
    fc = pad_spring(o, s0 + a * (s1 - s0), dc, core)[0]
    return 0.5 * ((f0 + fc) * a + (fc + f1) * (1.0 - a))


@njit(cache=True)
def half_plane_contact(face: float, cphi: float, sphi: float, ax: float, ay: float, bx: float,
                       by: float) -> tuple[float, float, float, float, float]:
    """``sim.contact.half_plane_contact``."""
    pa = sphi * ax + cphi * ay - face
    pb = sphi * bx + cphi * by - face
    nx = -sphi
    ny = -cphi
    if pa <= 0.0 and pb <= 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0
    if pa > 0.0 and pb > 0.0:
        return 1.0, 0.5 * (pa + pb), (pa + 2.0 * pb) / (3.0 * (pa + pb)), nx, ny
    if pb > 0.0:
        t0 = pa / (pa - pb)
        frac = 1.0 - t0
        return frac, 0.5 * pb, t0 + frac * 2.0 / 3.0, nx, ny
    t0 = pa / (pa - pb)
    return t0, 0.5 * pa, t0 / 3.0, nx, ny


@njit(cache=True)
def block_core(o: np.ndarray, cphi: float, sphi: float, ax: float, ay: float, bx: float,
               by: float) -> tuple[float, float, float]:
    """``sim.contact.block_core`` over the object array."""
    sc, dc, tc, _, _ = half_plane_contact(o[2] + o[6], cphi, sphi, ax, ay, bx, by)
    return sc, dc, tc


@njit(cache=True)
def pad_contact(o: np.ndarray, cphi: float, sphi: float, ax: float, ay: float, bx: float,
                by: float) -> tuple[float, float, float, float, float]:
    """``sim.contact.pad_contact`` over the object array."""
    if o[0] == KIND_CYLINDER:
        cx = cphi * o[1] + sphi * o[2]
        cy = -sphi * o[1] + cphi * o[2]
        ex = bx - ax
        ey = by - ay
        t = ((cx - ax) * ex + (cy - ay) * ey) / (ex * ex + ey * ey)
        if 0.0 < t < 1.0:
            el = math.sqrt(ex * ex + ey * ey)
            mx = -ey / el
            my = ex / el
            h = (cx - ax) * mx + (cy - ay) * my
            if h <= 0.0:
                if h <= -o[3]:
                    return 0.0, 0.0, 0.0, 0.0, 0.0
                return 1.0, o[3] - h, t, -mx, -my
        t = 0.0 if t < 0.0 else (1.0 if t > 1.0 else t)
        px = ax + t * ex
        py = ay + t * ey
        dx = px - cx
        dy = py - cy
        dist = math.sqrt(dx * dx + dy * dy)
        depth = o[3] - dist
        if depth <= 0.0 or dist < 1e-12:
            return 0.0, 0.0, 0.0, 0.0, 0.0
        return 1.0, depth, t, dx / dist, dy / dist
    if o[0] == KIND_BLOCK:
        return half_plane_contact(o[2], cphi, sphi, ax, ay, bx, by)
    return 0.0, 0.0, 0.0, 0.0, 0.0


@njit(cache=True)
def motor_effort(x: np.ndarray, c: np.ndarray, k: np.ndarray, e: np.ndarray,
                 dt: float) -> tuple[float, float, float]:
    """Servo set-point ramp, P controller, effort effects: (set-point, effort, asked effort)."""
    ref = x[X_REF]
    mode = c[0]
    goal = c[1]
    speed = c[2]
    if speed <= 0.0 or mode == MODE_FORCE:
        ref = goal
    else:
        step = speed * dt
        if goal - ref > step:
            ref += step
        elif goal - ref < -step:
            ref -= step
        else:
            ref = goal
    tl = c[4]
    limit = k[K_UMAX] * (0.0 if tl < 0.0 else (1.0 if tl > 1.0 else tl))
    u_cmd = c[3] if mode == MODE_FORCE else k[K_KP] * (ref - x[X_TH] - e[E_OFFSET])
    if u_cmd > limit:
        u_cmd = limit
    elif u_cmd < -limit:
        u_cmd = -limit
    u = u_cmd
    if e[E_GAIN] != 1.0:
        u *= e[E_GAIN]
    if e[E_SAT] != math.inf:
        cap = e[E_SAT] * k[K_UPN]
        u = min(max(u, -cap), cap)
    if e[E_LAG] > 0.0:
        u = x[X_U] + dt / (e[E_LAG] + dt) * (u - x[X_U])
    return ref, u, u_cmd


@njit(cache=True)
def speed_friction(v: float, k: np.ndarray) -> tuple[float, float]:
    """``sim.params.speed_friction_at`` over the pieces in ``k``: (friction units, slope)."""
    w = -v if v < 0.0 else v
    w0 = k[K_SPIECES]
    g0 = k[K_SPIECES + 1]
    expo = k[K_SPIECES + 2]
    if w <= w0:
        slope = g0 / w0
        return slope * v, slope
    for j in range(1, 3):
        if w < k[K_SPIECES + 3 * j]:
            break
        w0 = k[K_SPIECES + 3 * j]
        g0 = k[K_SPIECES + 3 * j + 1]
        expo = k[K_SPIECES + 3 * j + 2]
    g = g0 * (w / w0) ** expo
    return (g if v > 0.0 else -g), expo * g / w


@njit(cache=True)
def motor_friction(v: float, k: np.ndarray, e: np.ndarray) -> tuple[float, float]:
    """``sim.motor.friction_force_n``: (friction force, its slope)."""
    vs = k[K_VS]
    level = k[K_FC0] + e[E_COULOMB]
    if e[E_STICTION] > 0.0:
        level += e[E_STICTION] * math.exp(-(v / (20.0 * vs)) ** 2)
    if e[E_ASYM] > 0.0 and v > 0.0:
        level += e[E_ASYM]
    xv = v / vs
    if xv > 20.0:
        return level, 0.0
    if xv < -20.0:
        return -level, 0.0
    th = math.tanh(xv)
    return level * th, level * (1.0 - th * th) / vs


def _drop_stale_cache() -> None:
    """Drop numba's cache of the compiled modules when any of their sources changed
    (:mod:`sim.compiled_cache`): run here, at import, before any compiled function is called."""
    from pathlib import Path

    from sim.compiled_cache import cache_dir_of, drop_stale

    where = cache_dir_of(motor_friction)
    if where is not None:
        drop_stale(Path(__file__).resolve().parent, where)


_drop_stale_cache()
