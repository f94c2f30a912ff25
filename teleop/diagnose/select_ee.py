"""Effect selection by equation error (inverse dynamics), under the shared rule
(:mod:`teleop.diagnose.criterion`): score on the regression rows, held-out gain with both
models fitted on the first 70 % of the recording and judged on the last 30 %."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from teleop.diagnose import candidates as cand
from teleop.diagnose import engine
from teleop.diagnose.axis_model import Array
from teleop.diagnose.ee_filter import EESignals
from teleop.diagnose.equation_error import (
    EE_EFFECTS,
    EEFit,
    ee_apply,
    ee_effect_fit,
    ee_fit,
    ee_rows,
)
from teleop.diagnose.fit import NUMERIC_FAILURES
from teleop.diagnose.library import Term
from teleop.diagnose.model import AxisNominal
from teleop.diagnose.results import DiagnoseOptions, EffectResult


def _ee_slice(sig: EESignals, sl: slice) -> EESignals:
    return EESignals(sig.t[sl], sig.x[sl], sig.v[sl], sig.a[sl],
                     None if sig.u is None else sig.u[sl], sig.fs_hz, sig.cutoff_hz, sig.step,
                     None if sig.v_law is None else sig.v_law[sl])


def _ee_holdout(sig: EESignals, nominal: AxisNominal, cur: EEState, aug: EEState, name: str,
                grid: tuple[float, ...], fixed_inertia: float) -> float:
    """Held-out gain: both models fitted on the first 70 %, effort error on the last 30 % (a
    catalog effect's constant scanned on its grid again; a library term's constant kept)."""
    n = len(sig.t)
    cut = int(0.7 * n)
    m = int(3 * sig.fs_hz / sig.cutoff_hz)
    train, test = _ee_slice(sig, slice(0, cut)), _ee_slice(sig, slice(cut, n))
    b = ee_fit(train, nominal, cur.base, fixed_inertia, cur.terms)
    a = (ee_effect_fit(train, nominal, cur.base, name, grid, fixed_inertia, cur.terms)
         if name in EE_EFFECTS else ee_fit(train, nominal, aug.base, fixed_inertia, aug.terms))
    errs = []
    for f in (b, a):
        r = ee_apply(test, nominal, f, fixed_inertia)[m: len(test.t) - m]
        errs.append(float(np.sum(np.where(np.isfinite(r), r, 1e6) ** 2)))
    return 1.0 - errs[1] / errs[0] if errs[0] > 0 else 0.0


@dataclass(frozen=True)
class EEState:
    """An equation-error fit and the effect constants and library terms it was fitted with."""

    fit: EEFit
    base: dict[str, float]
    terms: tuple[Term, ...] = ()


@dataclass(frozen=True)
class EEPath:
    """The equation-error path for the engine (:mod:`teleop.diagnose.engine`): the score on
    the regression rows, held-out gain on the last 30 % of the recording."""

    sig: EESignals
    nominal: AxisNominal
    fixed_inertia: float
    grids: dict[str, tuple[float, ...]]

    def rss(self, f: EEState) -> float:
        return f.fit.rss

    def residual(self, f: EEState) -> Array:
        return f.fit.residual[ee_rows(self.sig)]

    def k_added(self, base: EEState, f: EEState) -> int:
        return f.fit.n_params - base.fit.n_params

    def at_floor(self, current: EEState, n_chosen: int) -> bool:
        return False  # the rule decides (the effort noise floor only gates the library terms)

    def holdout(self, current: EEState, name: str, f: EEState) -> tuple[float, bool]:
        return _ee_holdout(self.sig, self.nominal, current, f, name,
                           self.grids.get(name, (1.0,)), self.fixed_inertia), True

    def fit_candidates(self, current: EEState, names: tuple[str, ...]
                       ) -> list[tuple[str, EEState]]:
        out = []
        for name in names:
            if name not in EE_EFFECTS:
                continue
            try:
                f = ee_effect_fit(self.sig, self.nominal, current.base, name,
                                  self.grids.get(name, (1.0,)), self.fixed_inertia,
                                  current.terms)
            except NUMERIC_FAILURES:
                continue  # disqualified
            if math.isfinite(f.bic):
                out.append((name, EEState(f, {**current.base,
                                              name: dict(f.extra).get(name, 1.0)},
                                          current.terms)))
        return out


def effect_result(name: str, f: EEFit, score: float, gain: float) -> EffectResult:
    extra = dict(f.extra)
    if name in extra:
        val = extra[name] if name != "stiction" else f.get("stiction")
    else:
        val = f.get(name)
    if name == "sensor_offset":
        k = f.get("stiffness") + f.get("gravity")
        val = val / k if k else val
    params = [(name, val)] + ([("stribeck_velocity", extra["stiction"])]
                              if name == "stiction" else []) + (
        [("asymmetric_viscous", f.get("asymmetric_viscous"))]
        if name == "asymmetric_friction" else [])
    return EffectResult(name, tuple(params), ((name, math.nan),), score, gain,
                        cand.explanation(name, val))


def catalog_ee(path: EEPath, start: EEState, opts: DiagnoseOptions, names: tuple[str, ...]
               ) -> tuple[engine.Selection[EEState], list[EffectResult], list[tuple[str, float]]]:
    """Forward selection by the engine on the equation error, from ``start``: the selection
    (every step, library terms included when ``path`` offers them), the catalog effects and
    the first step's ranking of catalog effects (effect, score)."""
    sel = engine.forward(path, start, names, opts.max_effects,
                         engine.Rule(criterion=opts.criterion))
    chosen = [effect_result(st.name, st.fit.fit, st.verdict.score, st.verdict.holdout_gain)
              for st in sel.steps if st.name in EE_EFFECTS]
    return sel, chosen, [(n, sc) for n, sc in sel.ranking if n in EE_EFFECTS]
