"""Equation-error (inverse dynamics) fits of the axis: linear least squares on filtered signals.

The position is low-passed with a zero-phase Butterworth filter and differentiated twice; every
regressor (input included) is the same number of filter passes away from the physics (two: the
filtered position's ``a``, ``v``, ``x`` get one more, the input, the friction law and every
other function of the state two), so linear terms satisfy the filtered equation exactly.  (The
input and the law used to get one pass against the position columns' two: on a stiff PD loop
with Coulomb friction that left an equation error 16x its noise, mostly at low speed.)  Effects
that enter nonlinearly through one constant (dead time, lag, saturation, Stribeck velocity) are
handled by a one-dimensional grid around the linear solve.  The signals (filter, derivatives,
the law's velocity) are :mod:`teleop.diagnose.ee_filter`'s."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from teleop.diagnose.axis_model import Array, AxisParams, delayed, input_effort, lagged
from teleop.diagnose.ee_filter import EESignals, _filt
from teleop.diagnose.library import Term, column
from teleop.diagnose.model import AxisNominal
from teleop.effects import EffectSet

EE_EFFECTS = ("dead_time", "coulomb_friction", "asymmetric_friction", "stiction",
              "actuator_saturation", "actuator_gain", "actuator_lag", "sensor_offset",
              "nonlinear_stiffness", "gravity")


@dataclass(frozen=True, slots=True)
class EEFit:
    """A linear equation-error fit: coefficients by column name and the effort residual."""

    names: tuple[str, ...]
    coef: tuple[float, ...]
    residual: Array      # effort residual on the full grid
    rss: float           # on the decimated rows
    n: int
    n_params: int
    extra: tuple[tuple[str, float], ...] = ()
    terms: tuple[Term, ...] = ()   # library terms (physics outside the catalog) in the fit

    def get(self, name: str, default: float = 0.0) -> float:
        """Coefficient ``name``."""
        return self.coef[self.names.index(name)] if name in self.names else default

    @property
    def bic(self) -> float:
        """Bayesian information criterion on the decimated rows."""
        return self.n * math.log(max(self.rss, 1e-300) / self.n) + self.n_params * math.log(self.n)


def _columns(sig: EESignals, nominal: AxisNominal, effects: dict[str, float],
             fixed_inertia: float, terms: tuple[Term, ...] = ()
             ) -> tuple[list[str], list[Array], list[tuple[float, float]], Array]:
    """Regressor columns (unfiltered), their bounds and the fixed-part target.

    With an actuator gain ``g`` (a scanned constant) the equation ``J a + ... = g u`` is
    divided by ``g``: target ``u``, every coefficient fitted as ``coef / g`` within its bounds
    divided by ``g``.  A free gain column instead lets the least squares shrink the whole
    equation (inertia to its lower bound, the gain with it): a smaller residual that is only a
    change of scale, once named on clean closed-loop data as a gain of 0.7 x the inertia's
    nominal."""
    g = _gain(sig, effects)
    x, v, a = sig.x, sig.v, sig.a
    sgn = sig.sign
    names: list[str] = []
    cols: list[Array] = []
    bnds: list[tuple[float, float]] = []
    target = np.zeros_like(x)         # efforts of unfiltered signals (the input)
    target_filt = np.zeros_like(x)    # efforts of the filtered position's signals
    term_cols = {"inertia": a, "viscous": v, "stiffness": x, "gravity": np.sin(x),
                 "coulomb": sgn, "offset": -np.ones_like(x)}
    for term in nominal.terms:
        if term == "inertia" and sig.u is None:
            continue
        names.append(term)
        cols.append(term_cols[term])
        lo_, hi_ = nominal.bounds(term)
        bnds.append((lo_ / g, hi_ / g))
    if sig.u is None:
        target_filt = target_filt - fixed_inertia * a
    else:
        ue = sig.u
        if "dead_time" in effects:
            ue = delayed(sig.t, ue, effects["dead_time"])
        if "actuator_saturation" in effects:
            s = effects["actuator_saturation"]
            ue = np.clip(ue, -s, s)
        if "actuator_lag" in effects:
            ue = lagged(sig.t, ue, effects["actuator_lag"])
        target = target + ue
        if "inertia" not in nominal.terms:
            target_filt = target_filt - fixed_inertia / g * a
    extra_cols = {
        "coulomb_friction": (sgn, (0.0, math.inf)),
        "asymmetric_friction": ((v > 0).astype(float), (0.0, math.inf)),
        "nonlinear_stiffness": (x ** 3, (-math.inf, math.inf)),
        "gravity": (np.sin(x), (-math.inf, math.inf)),
        "sensor_offset": (np.ones_like(x), (-math.inf, math.inf)),
    }
    for name, (col, bd) in extra_cols.items():
        if name in effects:
            names.append(name)
            cols.append(col)
            bd_ = bd
            cols[-1] = col
            bnds.append(bd_)
    if "asymmetric_friction" in effects:  # direction-dependent viscous level as well
        names.append("asymmetric_viscous")
        cols.append(v * (v > 0))
        bnds.append((-math.inf, math.inf))
    if "stiction" in effects:
        vs = effects["stiction"]
        names.append("stiction")
        cols.append(sgn * np.exp(-(v / vs) ** 2))
        bnds.append((0.0, math.inf))
    for term in terms:   # an effort added to the load: J a = ... + c phi
        names.append(term.key)
        cols.append(-column(term, sig.t, x, v, sig.u))
        bnds.append((-math.inf, math.inf))
    # every column the same filter passes away from the physics: a, v and x are the filtered
    # position's (one pass), so what stands for an unfiltered signal (the input, the friction
    # law, any other function of the state) gets one pass here; the fit gives all one more
    lin = {"inertia", "viscous", "stiffness"}
    cols = [c if n in lin else _filt(c, sig.fs_hz, sig.cutoff_hz)
            for n, c in zip(names, cols, strict=True)]
    return names, cols, bnds, target_filt + _filt(target, sig.fs_hz, sig.cutoff_hz)


SCANNED = ("dead_time", "actuator_lag", "actuator_saturation", "stiction", "actuator_gain")
"""Effects whose constant is scanned on a grid (each counts as one parameter)."""


def _gain(sig: EESignals, effects: dict[str, float]) -> float:
    return effects.get("actuator_gain", 1.0) if sig.u is not None else 1.0


def ee_rows(sig: EESignals) -> slice:
    """The regression rows: decimated, the filter's transients at both ends left out."""
    margin = int(3 * sig.fs_hz / sig.cutoff_hz) + 1
    return slice(margin, len(sig.t) - margin, sig.step)


def ee_fit(sig: EESignals, nominal: AxisNominal, effects: dict[str, float] | None = None,
           fixed_inertia: float = 1.0, terms: tuple[Term, ...] = ()) -> EEFit:
    """Bounded linear least squares of the equation error with ``effects`` (name -> constant)
    and library ``terms`` (a scanned wavenumber or delay counts as one more parameter)."""
    effects = effects or {}
    names, cols, bnds, target = _columns(sig, nominal, effects, fixed_inertia, terms)
    fs, fc = sig.fs_hz, sig.cutoff_hz
    phi = _filt(np.column_stack(cols), fs, fc) if cols else np.zeros((len(target), 0))
    tgt = _filt(target, fs, fc)
    rows = ee_rows(sig)
    A, b = phi[rows], tgt[rows]
    if A.shape[1]:
        scale = np.maximum(np.sqrt(np.mean(A ** 2, axis=0)), 1e-300)
        lo = np.array([bd[0] for bd in bnds]) * scale
        hi = np.array([bd[1] for bd in bnds]) * scale
        res = optimize.lsq_linear(A / scale, b, bounds=(lo, hi), method="bvls")
        coef = res.x / scale
        coef = coef * _gain(sig, effects)   # the physical coefficients (see _columns)
    else:
        coef = np.zeros(0)
    resid_full = (phi @ coef / _gain(sig, effects) - tgt) if A.shape[1] else -tgt
    r = resid_full[rows]
    n_eff_params = len(names) + sum(1 for k in effects if k in SCANNED) + sum(
        1 for t in terms if t.kind in ("sin", "udelay"))
    extra = tuple((k, v) for k, v in effects.items() if k in SCANNED)
    return EEFit(tuple(names), tuple(float(c) for c in coef), resid_full, float(r @ r), len(r),
                 n_eff_params, extra, terms)


def ee_effect_fit(sig: EESignals, nominal: AxisNominal, base: dict[str, float], name: str,
                  grid: tuple[float, ...], fixed_inertia: float,
                  terms: tuple[Term, ...] = ()) -> EEFit:
    """Best equation-error fit of ``base`` plus effect ``name`` (grid over its constant)."""
    best: EEFit | None = None
    for g in grid:
        fit = ee_fit(sig, nominal, {**base, name: g}, fixed_inertia, terms)
        if best is None or fit.rss < best.rss:
            best = fit
    assert best is not None
    return best


def model_equation_error(sig: EESignals, p: AxisParams, eff: EffectSet) -> Array:
    """Effort residual ``J a - (sum of modelled efforts)`` of a full model on filtered signals.

    Backlash and series compliance are ignored here (they need the hidden load state).
    """
    x = sig.x - eff.sensor_offset
    v, a = sig.v, sig.a
    f = (np.zeros_like(x) if sig.u is None
         else _filt(input_effort(sig.t, sig.u, eff), sig.fs_hz, sig.cutoff_hz))
    eps = 0.02 * float(np.std(v)) + 1e-12
    sgn = np.tanh(v / eps)
    fric = (p.coulomb + eff.coulomb_friction) * sgn + eff.asymmetric_friction * (v > 0)
    if eff.stiction > 0:
        fric = fric + eff.stiction * sgn * np.exp(-(v / max(p.stribeck_velocity, 1e-12)) ** 2)
    total = (f - p.viscous * v - p.stiffness * x + p.offset - (p.gravity + eff.gravity)
             * np.sin(x) - eff.nonlinear_stiffness * x ** 3 - fric)
    return p.inertia * a - total


def fit_effects(fit: EEFit, nominal: AxisNominal) -> dict[str, float]:
    """The effects (name -> constant) ``fit`` was fitted with."""
    effects = dict(fit.extra)
    for n in fit.names:
        if n in EE_EFFECTS and n not in nominal.terms and n not in effects:
            effects[n] = 1.0
    return effects


def ee_apply(sig: EESignals, nominal: AxisNominal, fit: EEFit, fixed_inertia: float) -> Array:
    """Effort residual of an already fitted equation-error model on other signals."""
    effects = fit_effects(fit, nominal)
    names, cols, _, target = _columns(sig, nominal, effects, fixed_inertia, fit.terms)
    gain = _gain(sig, effects)
    coef = {n: c / gain for n, c in zip(fit.names, fit.coef, strict=True)}
    fs, fc = sig.fs_hz, sig.cutoff_hz
    total = sum((coef[n] * _filt(c, fs, fc) for n, c in zip(names, cols, strict=True)),
                np.zeros(len(target)))
    return total - _filt(target, fs, fc)
