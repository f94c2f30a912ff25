"""A generic one-degree-of-freedom mechanical axis, with every catalog effect it can carry.

Load equation (effort units: N or N m; position units: m or rad)::

    J x'' = f - b x' - k x - g sin(x) - c sgn(x') + f0          (nominal terms)
            - k3 x^3 - friction extras                          (catalog effects)

``f`` is the effort reaching the load: the input ``u`` delayed (``dead_time``), clipped
(``actuator_saturation``), scaled (``actuator_gain``), low-passed (``actuator_lag``) and passed
through a spring to the load (``series_compliance``; the actuator side then has a rotor inertia
of ``ROTOR_FRACTION * J`` and 5 % critical spring damping).  The sensed position is the load
position seen through a transmission dead band (``backlash``, a play operator) plus
``sensor_offset``.  Friction: Coulomb level ``c + coulomb_friction``, ``asymmetric_friction``
extra while moving positively, ``stiction`` extra near zero velocity with a Gaussian Stribeck
decay of width ``stribeck_velocity``; the load sticks when the other forces cannot break it away.

Integration: the linear part exactly (matrix exponential), the other efforts held over each
sub-step; sub-stepped so no step exceeds ``max_dt_s``.  It is a plain float loop (about a
microsecond per step).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from teleop.diagnose import axis_kernel, library
from teleop.effects import EffectSet

Array = NDArray[np.float64]

#: Nominal model terms of the axis, in the order used everywhere.
AXIS_TERMS: tuple[str, ...] = ("inertia", "viscous", "stiffness", "gravity", "coulomb", "offset")

#: Actuator-side (rotor) inertia as a fraction of the load inertia when a series spring acts.
ROTOR_FRACTION = 0.1
#: Spring damping ratio used with series compliance.
SPRING_DAMPING_RATIO = 0.05


@dataclass(frozen=True, slots=True)
class AxisParams:
    """Physical constants of the axis (effort per position/velocity/acceleration units)."""

    inertia: float = 1.0
    viscous: float = 0.0
    stiffness: float = 0.0
    gravity: float = 0.0
    coulomb: float = 0.0
    offset: float = 0.0
    stribeck_velocity: float = 0.1
    input_shift_s: float = 0.0   # sample alignment of the input (see ``input_effort``)
    terms: tuple[tuple[str, float], ...] = ()   # library terms (``library.py``): key, coef

    def with_terms(self, values: dict[str, float]) -> AxisParams:
        """A copy with some terms replaced."""
        return replace(self, **values)


def delayed(t: Array, u: Array, delay_s: float, before: float | None = None) -> Array:
    """``u(t - delay)`` (a negative delay is a lead); before the record the input is ``before``
    (default: the first sample held), after it the last sample is held."""
    if delay_s == 0.0:
        return u
    return np.interp(t - delay_s, t, u, left=u[0] if before is None else before, right=u[-1])


def lagged(t: Array, f: Array, tau_s: float) -> Array:
    """First-order lag (time constant ``tau_s``) of ``f`` sampled at ``t`` (exact, held input)."""
    if tau_s <= 0.0:
        return f
    out = np.empty_like(f)
    y = float(f[0])
    out[0] = y
    dts = np.diff(t)
    alphas = np.exp(-dts / tau_s)
    fl = f.tolist()
    al = alphas.tolist()
    for i in range(1, len(fl)):
        a = al[i - 1]
        y = a * y + (1.0 - a) * fl[i - 1]
        out[i] = y
    return out


def play(x: Array, width: float) -> Array:
    """Play (backlash) operator of total width ``width``: the output moves only when pushed."""
    if width <= 0.0:
        return x
    h = 0.5 * width
    xl = x.tolist()
    y = xl[0]
    out = np.empty_like(x)
    for i, xi in enumerate(xl):
        if xi - y > h:
            y = xi - h
        elif y - xi > h:
            y = xi + h
        out[i] = y
    return out


def input_effort(t: Array, u: Array, eff: EffectSet, shift_s: float = 0.0,
                 before: float | None = None) -> Array:
    """The actuator effort before the series spring: delay, saturation, gain and lag applied.

    ``shift_s`` is the input's sample alignment, a nominal nuisance within one sample period
    (signed): a recording does not say whether an input sample is held until the next one
    (zero-order hold) or passes through a continuous signal, nor whether it was logged at the
    start or end of its period; a half-sample mismatch alone moves a fast axis by more than
    the noise.  ``dead_time`` is a delay beyond that alignment; with a delay, the input before
    the record (``before``; default: the first sample held) acts at the start."""
    f = delayed(t, u, eff.dead_time + shift_s, before)
    if math.isfinite(eff.actuator_saturation):
        f = np.clip(f, -eff.actuator_saturation, eff.actuator_saturation)
    if eff.actuator_gain != 1.0:
        f = f * eff.actuator_gain
    return lagged(t, f, eff.actuator_lag)


def _transition(J: float, b: float, k: float, dt: float) -> tuple[float, ...]:
    """Exact one-step map of ``J x'' = F - b x' - k x`` with F held: (p00, p01, p10, p11, g0, g1).

    Matrix exponential of the 3x3 augmented system by scaling and squaring of a Taylor series
    (pure Python: small and free of BLAS thread start-up).
    """
    m = [[0.0, dt, 0.0], [-k / J * dt, -b / J * dt, dt / J], [0.0, 0.0, 0.0]]
    norm = max(sum(abs(v) for v in row) for row in m)
    sq = 0
    while norm > 0.25:
        norm *= 0.5
        sq += 1
    f = 0.5 ** sq
    m = [[v * f for v in row] for row in m]

    def mul(a: list[list[float]], c: list[list[float]]) -> list[list[float]]:
        return [[sum(a[i][r] * c[r][j] for r in range(3)) for j in range(3)] for i in range(3)]

    e = [[1.0 if i == j else 0.0 for j in range(3)] for i in range(3)]
    term = [row[:] for row in e]
    for n in range(1, 14):
        term = [[v / n for v in row] for row in mul(term, m)]
        e = [[e[i][j] + term[i][j] for j in range(3)] for i in range(3)]
    for _ in range(sq):
        e = mul(e, e)
    return (e[0][0], e[0][1], e[1][0], e[1][1], e[0][2], e[1][2])


def _step_maps(t: Array, J: float, b: float, k: float, max_dt_s: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(row of each sample interval, one-step maps, sub-steps, sub-step length): one row per
    distinct interval length (one for a uniformly sampled record)."""
    dts = np.diff(t)

    def step_map(dt_total: float) -> tuple[int, float, tuple[float, ...]]:
        nsub = max(1, int(math.ceil(dt_total / max_dt_s - 1e-9)))
        return nsub, dt_total / nsub, _transition(J, b, k, dt_total / nsub)

    if float(np.ptp(dts)) <= 1e-9 * float(np.median(dts)):
        rows = [step_map(float(np.median(dts)))]
        which = np.zeros(len(dts), dtype=np.int64)
    else:
        # keyed by the length rounded to 1e-12 s; each key's map from its first interval
        _, first, which = np.unique(np.round(dts, 12), return_index=True, return_inverse=True)
        rows = [step_map(float(dts[i])) for i in first]
        which = which.astype(np.int64).ravel()
    return (which, np.array([r[2] for r in rows]), np.array([r[0] for r in rows], np.int64),
            np.array([r[1] for r in rows]))


def simulate_axis(t: Array, u: Array | None, p: AxisParams, eff: EffectSet = EffectSet(),
                  x0: float = 0.0, v0: float = 0.0, max_dt_s: float = 1e-3,
                  u_before: float | None = None) -> Array:
    """Sensed position at the sample times ``t`` (no noise), from ``x(t0)=x0, x'(t0)=v0``.

    The linear part (inertia, viscous, stiffness) is integrated exactly over each sub-step; the
    other efforts (input, gravity, cubic spring, friction, series spring) are held over it.
    ``u_before``: the input before the record (acts through a delay; default the first sample).
    A diverging simulation returns NaN from the point it blew up.
    """
    n = len(t)
    f_in = np.zeros(n) if u is None else input_effort(t, np.asarray(u, float), eff,
                                                                p.input_shift_s, u_before)
    coefs = dict(p.terms)
    if u is not None:
        for d, c in library.input_terms(coefs):
            f_in = f_in + c * delayed(t, np.asarray(u, float), d + p.input_shift_s)
    J = p.inertia
    b, k = p.viscous, p.stiffness
    series = math.isfinite(eff.series_compliance)
    ks = eff.series_compliance if series else 0.0
    ja = ROTOR_FRACTION * J
    cs = 2.0 * SPRING_DAMPING_RATIO * math.sqrt(ks * ja * J / (ja + J)) if series else 0.0
    if series:
        max_dt_s = min(max_dt_s, 0.2 / math.sqrt(ks / ja + ks / J))
    fc = p.coulomb + eff.coulomb_friction
    friction = fc > 0.0 or eff.asymmetric_friction > 0.0 or eff.stiction > 0.0
    consts = np.array([k, p.offset, p.gravity + eff.gravity, eff.nonlinear_stiffness, fc,
                       eff.asymmetric_friction, eff.stiction, max(p.stribeck_velocity, 1e-12),
                       ks, cs, ja, float(friction), float(series)])
    x, v = float(x0), float(v0)
    xa = x + float(f_in[0]) / ks if series and n else x  # actuator side (series spring)
    out = np.empty(n)
    if n:
        out[0] = x
    if n > 1:
        which, maps, nsubs, dts = _step_maps(t, J, b, k, max_dt_s)
        kinds, tc, tw = library.state_terms(coefs)
        axis_kernel.kernel()(np.ascontiguousarray(f_in, dtype=np.float64), which, maps, nsubs,
                             dts, kinds, tc, tw, consts, np.array([x, v, xa, v]), out)
    y = play(out, eff.backlash) if eff.backlash > 0 else out
    if eff.sensor_offset != 0.0:
        y = y + eff.sensor_offset
    return y
