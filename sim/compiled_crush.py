"""The yielding object of :mod:`sim.crush` over the object array ``o`` of
:mod:`sim.compiled_kernel` (``o[8]`` yield force N, ``o[9]`` yield hardening N/m): the same
arithmetic in the same order as the Python functions of that name.

Numba's disk cache keys each function on its own file only, not on the kernels it
inlines; :mod:`sim.compiled_cache` drops the cache of every compiled module when any of
their sources changes, so an edit of the step or of the array layouts recompiles this
file's functions too.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sim.compiled_kernel import KIND_BLOCK, block_core, pad_spring


@njit(cache=True)
def pad_dent(o: np.ndarray, crush: float, depth: float) -> float:
    """``sim.crush.pad_dent`` over the object array."""
    k = o[4]
    plastic = (k * depth - o[8]) / (k + o[9])
    return plastic if plastic > crush else crush


@njit(cache=True)
def yield_pad_spring(o: np.ndarray, scale: float, depth: float,
                     crush: float, core: bool = True) -> tuple[float, float, float, float]:
    """``sim.crush.yield_pad_spring`` over the object array."""
    k = o[4]
    h = o[9]
    dent = pad_dent(o, crush, depth)
    rate = 1.0
    if dent > crush:
        crush = dent
        rate = h / (k + h)
    force = 0.0
    ke = 0.0
    elastic = depth - crush
    if elastic > 0.0:
        force = k * scale * elastic
        ke = k * scale * rate
    else:
        rate = 0.0
    if core and depth > o[6]:
        kc = o[7] * scale
        force += kc * (depth - o[6])
        ke += kc
    return force, ke, rate, crush


@njit(cache=True)
def pad_law(o: np.ndarray, scale: float, depth: float,
            crush: float, core: bool = True) -> tuple[float, float, float, float]:
    """``sim.crush.pad_law`` over the object array."""
    if o[8] > 0.0:
        fe, ke, rate, crush = yield_pad_spring(o, scale, depth, crush, core)
        return fe, ke, o[5] * scale * rate, crush
    fe, ke = pad_spring(o, scale, depth, core)
    return fe, ke, o[5] * scale, crush


@njit(cache=True)
def block_law(o: np.ndarray, scale: float, depth: float, t: float, core_scale: float,
              core_depth: float, core_t: float,
              crush: float) -> tuple[float, float, float, float, float]:
    """``sim.crush.block_law`` over the object array."""
    fe, ke, ce, crush = pad_law(o, scale, depth, crush, False)
    if core_depth > 0.0:
        kc = o[7] * core_scale
        fc = kc * core_depth
        t = (fe * t + fc * core_t) / (fe + fc)
        fe += fc
        ke += kc
    return fe, ke, ce, t, crush


@njit(cache=True)
def pad_force(o: np.ndarray, cphi: float, sphi: float, ax: float, ay: float, bx: float,
              by: float, scale: float, depth: float, t: float,
              crush: float) -> tuple[float, float, float, float, float]:
    """``sim.crush.pad_force`` over the object array."""
    if o[0] == KIND_BLOCK:
        sc, dc, tc = block_core(o, cphi, sphi, ax, ay, bx, by)
        return block_law(o, scale, depth, t, sc, dc, tc, crush)
    fe, ke, ce, crush = pad_law(o, scale, depth, crush)
    return fe, ke, ce, t, crush


@njit(cache=True)
def mean_yield_force(o: np.ndarray, s0: float, d0: float, c0: float, s1: float,
                     d1: float, core: bool = True) -> float:
    """``sim.crush.mean_yield_force`` over the object array."""
    f_prev = yield_pad_spring(o, s0, d0, c0, core)[0]
    dd = d1 - d0
    if dd == 0.0:
        return 0.5 * (f_prev + yield_pad_spring(o, s1, d1, c0, core)[0])
    d_yield = c0 + (o[8] + o[9] * c0) / o[4]
    cuts = np.array([(c0 - d0) / dd, (d_yield - d0) / dd, (o[6] - d0) / dd])
    cuts.sort()
    total = 0.0
    a_prev = 0.0
    for a in cuts:
        if 0.0 < a < 1.0:
            f = yield_pad_spring(o, s0 + a * (s1 - s0), d0 + a * dd, c0, core)[0]
            total += 0.5 * (f_prev + f) * (a - a_prev)
            f_prev = f
            a_prev = a
    return total + 0.5 * (f_prev + yield_pad_spring(o, s1, d1, c0, core)[0]) * (1.0 - a_prev)


@njit(cache=True)
def yield_pad_work(s0: float, d0: float, c0: float, s1: float, d1: float, c1: float,
                   o: np.ndarray, dt: float, core: bool = True) -> float:
    """``sim.crush.yield_pad_work_j`` over the object array."""
    if d0 <= 0.0 and d1 <= 0.0:
        return 0.0
    dd = d1 - d0
    e0 = d0 - c0 if d0 > c0 else 0.0
    e1 = d1 - c1 if d1 > c1 else 0.0
    elastic = mean_yield_force(o, s0, d0, c0, s1, d1, core)
    c = o[5]
    damping = c * 0.5 * (s0 + s1) * (e1 - e0) / dt if dt > 0.0 else 0.0
    force = max(elastic + damping, 0.0)
    return force * dd
