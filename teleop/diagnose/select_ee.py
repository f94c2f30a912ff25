"""Effect selection by equation error (inverse dynamics), under the shared rule
(:mod:`teleop.diagnose.criterion`): score on the regression rows, held-out gain with both
models fitted on the first 70 % of the recording and judged on the last 30 %."""

from __future__ import annotations

import math

import numpy as np

from teleop.diagnose import candidates as cand
from teleop.diagnose import criterion as crit
from teleop.diagnose.equation_error import (
    EE_EFFECTS,
    EEFit,
    EESignals,
    ee_apply,
    ee_effect_fit,
    ee_fit,
)
from teleop.diagnose.fit import NUMERIC_FAILURES
from teleop.diagnose.model import AxisNominal
from teleop.diagnose.results import DiagnoseOptions, EffectResult
from teleop.diagnose.select import _ee_grids


def _ee_score(base: EEFit, aug: EEFit, sig: EESignals) -> float:
    """The shared rule's score on the equation-error rows (decimated residual)."""
    r = aug.residual[::max(sig.step, 1)]
    r = r[np.isfinite(r)]
    return crit.score(base.rss, aug.rss, aug.n, aug.n_params - base.n_params,
                      min(crit.effective_n(r), float(aug.n)))


def _ee_slice(sig: EESignals, sl: slice) -> EESignals:
    return EESignals(sig.t[sl], sig.x[sl], sig.v[sl], sig.a[sl],
                     None if sig.u is None else sig.u[sl], sig.fs_hz, sig.cutoff_hz, sig.step)


def _ee_holdout(sig: EESignals, nominal: AxisNominal, base: dict[str, float], name: str,
                grid: tuple[float, ...], fixed_inertia: float) -> float:
    """Held-out gain: both models fitted on the first 70 %, effort error on the last 30 %."""
    n = len(sig.t)
    cut = int(0.7 * n)
    m = int(3 * sig.fs_hz / sig.cutoff_hz)
    train, test = _ee_slice(sig, slice(0, cut)), _ee_slice(sig, slice(cut, n))
    b = ee_fit(train, nominal, base, fixed_inertia)
    a = ee_effect_fit(train, nominal, base, name, grid, fixed_inertia)
    errs = []
    for f in (b, a):
        r = ee_apply(test, nominal, f, fixed_inertia)[m: len(test.t) - m]
        errs.append(float(np.sum(np.where(np.isfinite(r), r, 1e6) ** 2)))
    return 1.0 - errs[1] / errs[0] if errs[0] > 0 else 0.0


def select_ee(sig: EESignals, nominal: AxisNominal, opts: DiagnoseOptions, names: tuple[str, ...],
               fixed_inertia: float, scales: cand.Scales
               ) -> tuple[EEFit, EEFit, list[EffectResult], list[tuple[str, float]]]:
    grids = _ee_grids(scales)
    base: dict[str, float] = {}
    nom = ee_fit(sig, nominal, base, fixed_inertia)
    current = nom
    chosen: list[EffectResult] = []
    ranking: list[tuple[str, float]] = []
    remaining = [n for n in names if n in EE_EFFECTS]
    while remaining and len(chosen) < opts.max_effects:
        fits = []
        for name in remaining:
            try:
                f = ee_effect_fit(sig, nominal, base, name, grids.get(name, (1.0,)),
                                  fixed_inertia)
            except NUMERIC_FAILURES:
                continue  # disqualified
            if not math.isfinite(f.bic):
                continue
            fits.append((_ee_score(current, f, sig), name, f))
        fits.sort(key=lambda x: -x[0])
        if not chosen:
            ranking = [(n, d) for d, n, _ in fits]
        pick = None
        for dbic, name, f in fits:
            if dbic < opts.criterion.min_score:
                break
            try:
                gain = _ee_holdout(sig, nominal, base, name, grids.get(name, (1.0,)),
                                   fixed_inertia)
            except NUMERIC_FAILURES:
                continue
            r = f.residual[::max(sig.step, 1)]
            if crit.judge(current.rss, f.rss, r, f.n_params - current.n_params, gain,
                          criterion=opts.criterion).accepted:
                pick = (dbic, name, f, gain)
                break
        if pick is None:
            break
        dbic, name, f, gain = pick
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
        chosen.append(EffectResult(name, tuple(params), ((name, math.nan),), dbic, gain,
                                   cand.explanation(name, val)))
        base = {**base, name: extra.get(name, 1.0)}
        current = f
        remaining = [n for d, n, _ in fits if n != name and d >= opts.criterion.min_score]
    return nom, current, chosen, ranking
