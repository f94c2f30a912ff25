"""The axis simulation's inner loop as one compiled call (numba), or plain Python without it.

:func:`integrate` is the sub-stepped integration of :func:`teleop.diagnose.axis_model.simulate_axis`
(its docstring has the model); the caller prepares the input effort per sample, the exact
one-step maps of the linear part (one row per distinct step length, ``which`` picks the row of
each sample interval) and the library's state terms as arrays (``kinds`` codes of
:data:`teleop.diagnose.library.STATE_KINDS`).  The same source runs interpreted when numba is
missing; compiled, a 60 s, 1 kHz simulation takes about a millisecond instead of ~0.1 s, which
is what the output-error fits spend their time on (hundreds of simulations per diagnosis).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np


def integrate(fl: np.ndarray, which: np.ndarray, maps: np.ndarray, nsubs: np.ndarray,
              dts: np.ndarray, kinds: np.ndarray, coefs: np.ndarray, waves: np.ndarray,
              consts: np.ndarray, state: np.ndarray, out: np.ndarray) -> None:
    """Fill ``out[1:]`` (``out[0]`` is the initial position) from ``state`` = (x, v, xa, va).

    ``consts`` = (k, f0, g, k3, fc, fa, fs, vs, ks, cs, ja, friction, series).  A diverging
    run leaves NaN from where it blew up.
    """
    k, f0, g, k3 = consts[0], consts[1], consts[2], consts[3]
    fc, fa, fs, vs = consts[4], consts[5], consts[6], consts[7]
    ks, cs, ja = consts[8], consts[9], consts[10]
    friction = consts[11] != 0.0
    series = consts[12] != 0.0
    x, v, xa, va = state[0], state[1], state[2], state[3]
    nterms = len(kinds)
    stuck = False
    big = 1e12
    n = len(out)
    for i in range(n - 1):
        r = which[i]
        p00, p01, p10, p11, g0, g1 = (maps[r, 0], maps[r, 1], maps[r, 2], maps[r, 3],
                                      maps[r, 4], maps[r, 5])
        nsub = nsubs[r]
        dt = dts[r]
        fi = fl[i]
        for _ in range(nsub):
            if series:
                fsp = ks * (xa - x) + cs * (va - v)
                va += (fi - fsp) / ja * dt
                xa += va * dt
                force = fsp
            else:
                force = fi
            force += f0
            if nterms:
                e = 0.0
                for j in range(nterms):
                    c = coefs[j]
                    kind = kinds[j]
                    if kind == 0:
                        e += c * math.sin(waves[j] * x)
                    elif kind == 1:
                        e += c * math.cos(waves[j] * x)
                    elif kind == 2:
                        e += c * v * abs(v)
                    elif kind == 3:
                        e += c * v * v * v
                    elif kind == 4:
                        e += c * v * v
                    elif kind == 5:
                        e += c * x * x
                    else:
                        e += c * x * x * x
                force += e
            if g != 0.0:
                force -= g * math.sin(x)
            if k3 != 0.0:
                force -= k3 * x * x * x
            if friction:
                if stuck:
                    f_rest = force - k * x
                    if -(fc + fs) <= f_rest <= fc + fs + fa:
                        continue  # stays stuck
                    stuck = False
                    s = 1.0 if f_rest > 0 else -1.0
                else:
                    s = 1.0 if v > 0 else (-1.0 if v < 0 else (1.0 if force - k * x > 0
                                                                else -1.0))
                q = v / vs  # Stribeck term; beyond |q| = 30 it is below 1e-390: zero
                level = fc + (fs * math.exp(-q * q) if -30.0 < q < 30.0 else 0.0) + (
                    fa if s > 0 else 0.0)
                fr = force - level * s
                vn = p10 * x + p11 * v + g1 * fr
                if vn * s < 0.0:
                    # the motion stops within the step; it sticks unless the other efforts
                    # overcome static friction, in which case it reverses
                    f_rest = force - k * x
                    if -(fc + fs) <= f_rest <= fc + fs + fa:
                        x += 0.5 * v * dt * v / (v - vn)
                        v = 0.0
                        stuck = True
                        continue
                    s = -s
                    level = fc + fs + (fa if s > 0 else 0.0)
                    fr = force - level * s
                    vn = p10 * x + p11 * v + g1 * fr
                x = p00 * x + p01 * v + g0 * fr
                v = vn
            else:
                x, v = p00 * x + p01 * v + g0 * force, p10 * x + p11 * v + g1 * force
        if not (-big < x < big and -big < v < big):
            for m in range(i + 1, n):
                out[m] = math.nan
            return
        out[i + 1] = x


_COMPILED: list[Callable[..., Any]] = []


def kernel() -> Callable[..., Any]:
    """:func:`integrate` compiled by numba (cached on disk), or as is when numba is missing."""
    if not _COMPILED:
        try:
            from numba import njit
        except ImportError:  # pragma: no cover - numba is a dependency; plain Python works too
            _COMPILED.append(integrate)
        else:
            _COMPILED.append(njit(cache=True, nogil=True)(integrate))
    return _COMPILED[0]


__all__ = ["integrate", "kernel"]
