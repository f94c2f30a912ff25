"""Output-error (simulation) fits of the axis model, nominal or augmented with catalog effects.

Parameters: the nominal model's refinable terms (within their bounds), one internal coordinate per
effect (see :mod:`teleop.diagnose.candidates`) and the initial position and velocity.  The
simulated output is compared with the measurement on the fit grid; ``scipy.optimize.least_squares``
(trust region reflective, bounded) minimises the sum of squares.  Uncertainty: the Gauss-Newton
covariance ``s^2 (J^T J)^-1`` at the solution.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy import optimize

from teleop.diagnose import candidates as cand
from teleop.diagnose import library
from teleop.diagnose.axis_model import Array, AxisParams, simulate_axis
from teleop.diagnose.model import AxisNominal
from teleop.effects import EffectSet

#: Nominal parameter: the input's sample alignment in s (``axis_model.input_effort``).
SHIFT = "input_shift"
#: With a dead time, the input before segment ``i``'s record is unknown: ``u_before_i``.
BEFORE = "u_before_"

NUMERIC_FAILURES = (OverflowError, ZeroDivisionError, ValueError, FloatingPointError,
                    np.linalg.LinAlgError)
"""Exceptions a candidate's simulation or fit may raise on absurd parameters."""


@dataclass(frozen=True, slots=True)
class Segment:
    """One recording on the output-error fit grid."""

    t: Array
    u: Array | None
    y: Array


@dataclass(frozen=True, slots=True)
class FitData:
    """The recordings on the output-error fit grid (each segment has its own initial state)."""

    segments: tuple[Segment, ...]
    max_dt_s: float
    scales: cand.Scales
    fixed_inertia: float
    stribeck_velocity: float

    @property
    def y(self) -> Array:
        """All measured samples, segment after segment."""
        return np.concatenate([s.y for s in self.segments])

    @property
    def has_input(self) -> bool:
        """Whether the model is driven by an input."""
        return self.segments[0].u is not None

    def state_names(self) -> tuple[str, ...]:
        """Initial-state parameter names, two per segment."""
        return tuple(n for i in range(len(self.segments)) for n in (f"x0_{i}", f"v0_{i}"))


@dataclass(frozen=True, slots=True)
class ModelFit:
    """A fitted model: parameters, their standard errors, residual sum of squares."""

    effects: tuple[str, ...]
    names: tuple[str, ...]
    theta: tuple[float, ...]
    sigma: tuple[float, ...]
    rss: float
    n: int
    y_fit: Array

    @property
    def n_params(self) -> int:
        """Number of fitted parameters."""
        return len(self.theta)

    @property
    def bic(self) -> float:
        """Bayesian information criterion."""
        return self.n * math.log(max(self.rss, 1e-300) / self.n) + self.n_params * math.log(self.n)

    def value(self, name: str) -> float:
        """A fitted parameter by name."""
        return self.theta[self.names.index(name)]

    def std(self, name: str) -> float:
        """Standard error of a fitted parameter."""
        return self.sigma[self.names.index(name)]

    def as_dict(self) -> dict[str, float]:
        """Parameter name -> value."""
        return dict(zip(self.names, self.theta, strict=True))


def free_terms(nominal: AxisNominal, has_input: bool) -> tuple[str, ...]:
    """Nominal terms refined by the fit (inertia is a unit choice for a free response); with an
    input, also its sample alignment (``SHIFT``, within one raw sample period)."""
    return tuple(t for t in nominal.terms if not (t == "inertia" and not has_input)) + (
        (SHIFT,) if has_input else ())


def build(names: tuple[str, ...], theta: Array | tuple[float, ...], data: FitData
          ) -> tuple[AxisParams, EffectSet]:
    """Model objects from a parameter vector."""
    vals = dict(zip(names, (float(v) for v in theta), strict=True))
    p = AxisParams(inertia=vals.get("inertia", data.fixed_inertia),
                   viscous=vals.get("viscous", 0.0), stiffness=vals.get("stiffness", 0.0),
                   gravity=vals.get("gravity", 0.0), coulomb=vals.get("coulomb", 0.0),
                   offset=vals.get("offset", 0.0),
                   stribeck_velocity=vals.get("stribeck_velocity", data.stribeck_velocity),
                   input_shift_s=vals.get(SHIFT, 0.0),
                   terms=library.resolve(vals))
    eff = EffectSet()
    for name, z in vals.items():
        if name.startswith("effect:"):
            en = name[7:]
            val = cand.to_effect_value(en, z, data.scales, data.max_dt_s)
            if en == "series_compliance" and not math.isfinite(val):
                continue
            eff = replace(eff, **{en: val})
    return p, eff


def simulate(names: tuple[str, ...], theta: Array | tuple[float, ...], data: FitData) -> Array:
    """Simulated measurement of every segment, concatenated."""
    p, eff = build(names, theta, data)
    vals = dict(zip(names, (float(v) for v in theta), strict=True))
    try:
        out = [simulate_axis(s.t, s.u, p, eff, vals[f"x0_{i}"], vals[f"v0_{i}"], data.max_dt_s,
                             vals.get(f"{BEFORE}{i}"))
               for i, s in enumerate(data.segments)]
    except NUMERIC_FAILURES:
        # a parameter vector the simulation cannot integrate is as bad as a divergent one
        return np.full(sum(len(s.t) for s in data.segments), math.nan)
    return np.concatenate(out)


def _bounds(name: str, nominal: AxisNominal, data: FitData) -> tuple[float, float]:
    if name.startswith("effect:"):
        return cand.bounds(name[7:], data.scales)
    if name.startswith(("x0_", "v0_")):
        return -math.inf, math.inf
    if name == "stribeck_velocity":
        return 0.002 * data.scales.velocity, 0.5 * data.scales.velocity
    if name == SHIFT:
        return -data.scales.dt_s, data.scales.dt_s
    if name.startswith(BEFORE):
        return -1.5 * data.scales.umax, 1.5 * data.scales.umax
    if name.startswith(library.PREFIX):
        return -math.inf, math.inf
    if name.startswith(library.WAVE):
        w0 = float(name[len(library.WAVE):])
        return 0.9 * w0, 1.1 * w0
    return nominal.bounds(name)


def _scale(name: str, start: float, data: FitData) -> float:
    s = data.scales
    if name.startswith("x0_"):
        return s.position
    if name.startswith("v0_"):
        return s.velocity
    if name == "stribeck_velocity":
        return 0.05 * s.velocity
    if name == "effect:dead_time" or name == "effect:actuator_lag":
        return 0.05
    if name == "effect:actuator_gain":
        return 1.0
    if name == SHIFT:
        return 0.5 * s.dt_s
    if name.startswith(BEFORE):
        return max(s.effort, 1e-12)
    if name.startswith(library.WAVE):
        return 0.01 * start
    return max(abs(start), 1e-6 * s.effort, 1e-12)


def _inside(v: float, lo: float, hi: float) -> float:
    """``v`` moved strictly inside ``(lo, hi)``."""
    span = hi - lo
    eps = 1e-6 * span if math.isfinite(span) else 1e-9 * max(abs(v), 1.0)
    if math.isfinite(lo) and v <= lo + eps:
        v = lo + eps
    if math.isfinite(hi) and v >= hi - eps:
        v = hi - eps
    return v


def guarded_residual(y_fit: Array, data: FitData) -> Array:
    """Simulated minus measured output, a sample the simulation could not give (not finite)
    counted as ten position scales off."""
    r = y_fit - data.y
    return np.where(np.isfinite(r), r, 10.0 * data.scales.position)


def fit_model(data: FitData, nominal: AxisNominal, start: dict[str, float],
              effects: tuple[str, ...] = (), max_nfev: int = 60,
              mask: Array | None = None) -> ModelFit:
    """Least-squares fit from ``start`` (name -> value; effect coordinates as ``effect:NAME``;
    every library term in ``start``, ``term:KIND:CONST``, is fitted too).

    ``mask`` (boolean on the fit grid) restricts the samples the fit sees (held-out checks).
    """
    names = tuple(free_terms(nominal, data.has_input)) + tuple(
        f"effect:{e}" for e in effects) + (("stribeck_velocity",) if "stiction" in effects
                                           else ()) + tuple(
        k for k in start if k.startswith((library.PREFIX, library.WAVE))) + data.state_names() + (
        tuple(f"{BEFORE}{i}" for i in range(len(data.segments))) if "dead_time" in effects
        else ())
    defaults = {"stribeck_velocity": data.stribeck_velocity,
                **{f"{BEFORE}{i}": float(sg.u[0]) for i, sg in enumerate(data.segments)
                   if sg.u is not None}}
    x_start = np.array([start.get(n, defaults.get(n, 0.0)) for n in names], float)
    lo = np.array([_bounds(n, nominal, data)[0] for n in names])
    hi = np.array([_bounds(n, nominal, data)[1] for n in names])
    x_start = np.array([_inside(v, a, b) for v, a, b in zip(x_start, lo, hi, strict=True)])
    xs = np.array([_scale(n, v, data) for n, v in zip(names, x_start, strict=True)])
    sel = np.ones(len(data.y), bool) if mask is None else mask

    def resid(th: Array) -> Array:
        return guarded_residual(simulate(names, th, data), data)[sel]

    res = optimize.least_squares(resid, x_start, bounds=(lo, hi), x_scale=xs,
                                 max_nfev=max_nfev, method="trf", diff_step=1e-4)
    y_fit = simulate(names, res.x, data)
    r = guarded_residual(y_fit, data)
    rss = float(r[sel] @ r[sel])
    n = int(sel.sum())
    jac = res.jac
    near = (res.x - lo < 1e-2 * xs) | (hi - res.x < 1e-2 * xs)
    free = (res.active_mask == 0) & ~near  # parameters held at a bound are not free to vary
    sigma = np.zeros(len(names))
    try:
        s2 = rss / max(n - int(free.sum()), 1)
        jf = jac[:, free]
        cov = np.linalg.pinv(jf.T @ jf) * s2
        sigma[free] = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except (np.linalg.LinAlgError, ValueError):
        sigma[:] = math.nan
    return ModelFit(tuple(effects), names, tuple(float(v) for v in res.x),
                    tuple(float(v) for v in sigma), rss, n, y_fit)


def scan_effect(data: FitData, base: ModelFit, name: str) -> dict[str, float]:
    """Grid start of effect ``name`` with the lowest error, other parameters at ``base``.

    Returns the start values to add (``effect:NAME``, and the Stribeck velocity for stiction).
    """
    key = f"effect:{name}"
    vs_grid: tuple[float | None, ...] = (None,)
    if name == "stiction":
        vs_grid = tuple(f * data.scales.velocity for f in (0.01, 0.03, 0.1))
    best, best_start = math.inf, {key: cand.start_grid(name, data.scales)[0]}
    y_meas = data.y
    base_d = base.as_dict()
    for vs in vs_grid:
        for z in cand.start_grid(name, data.scales):
            st = {key: z} if vs is None else {key: z, "stribeck_velocity": vs}
            d = {**base_d, **st}
            names = tuple(d)
            ys = simulate(names, tuple(d.values()), data)
            r = ys - y_meas
            rss = float(r @ r) if np.all(np.isfinite(r)) else math.inf
            if rss < best:
                best, best_start = rss, st
    return best_start
