"""Output-error diagnosis of any :class:`~teleop.diagnose.model.NominalModel` (e.g. the finger).

Used for models the library does not know (the CLI wires them in from ``sim/``).  Suited to
short or static recordings: the measurement noise is given (``noise_std``, e.g. an instrument's
resolution) rather than estimated.  Effects are kept under the shared rule
(:mod:`teleop.diagnose.criterion`, known-noise form); with a few static points there is no
held-out part, so the score alone decides.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from teleop.diagnose import criterion as crit
from teleop.diagnose.axis_model import Array
from teleop.diagnose.candidates import explanation, neutral
from teleop.diagnose.diagnose import EffectResult, nrmse
from teleop.diagnose.model import NominalModel
from teleop.effects import CATALOG, EffectSet


@dataclass(frozen=True, slots=True)
class GenericDiagnosis:
    """Result of :func:`diagnose_model` (same JSON contract as the axis diagnosis)."""

    nominal_params: tuple[tuple[str, float], ...]
    final_params: tuple[tuple[str, float], ...]
    effects: tuple[EffectResult, ...]
    ranking: tuple[tuple[str, float], ...]
    nrmse_before: float
    nrmse_after: float
    y: Array
    y_nominal: Array
    y_final: Array


def _fit(model: NominalModel, t: Array, u: Array | None, y: Array, effects: tuple[str, ...],
         start: Array, lo: Array, hi: Array) -> tuple[Array, float, Array]:
    k = len(model.param_names())

    def eff_of(x: Array) -> EffectSet:
        e = EffectSet()
        for name, v in zip(effects, x[k:], strict=True):
            e = e.with_effect(name, float(v))
        return e

    def resid(x: Array) -> Array:
        return model.simulate(x[:k], eff_of(x), t, u) - y

    x0 = np.clip(start, lo + 1e-9 * np.abs(lo) + 1e-12, hi - 1e-9 * np.abs(hi) - 1e-12)
    res = optimize.least_squares(resid, x0, bounds=(lo, hi), x_scale=np.maximum(np.abs(x0),
                                                                                  1e-3),
                                 max_nfev=60, diff_step=1e-3)
    r = res.fun
    try:
        cov = np.linalg.pinv(res.jac.T @ res.jac)
        sd = np.sqrt(np.clip(np.diag(cov), 0, None))
    except (np.linalg.LinAlgError, ValueError):
        sd = np.full(len(res.x), math.nan)
    return res.x, float(r @ r), sd


def diagnose_model(model: NominalModel, t: Array, u: Array | None, y: Array, noise_std: float,
                   starts: dict[str, tuple[float, ...]], effect_bounds: dict[str, tuple[float,
                                                                                         float]],
                   criterion: crit.Criterion = crit.DEFAULT, max_effects: int = 2
                   ) -> GenericDiagnosis:
    """Fit the nominal model, then each candidate effect; keep what lowers the BIC enough."""
    n = len(y)
    names = model.param_names()
    lo0, hi0 = model.bounds()
    x_nom, rss_nom, _ = _fit(model, t, u, y, (), model.initial(), lo0, hi0)

    def score(rss0: float, rss1: float) -> float:
        return crit.score(rss0, rss1, n, 1, float(n), noise_std)

    current_eff: tuple[str, ...] = ()
    current_x = x_nom
    current_rss = rss_nom
    chosen: list[EffectResult] = []
    ranking: list[tuple[str, float]] = []
    cands = [c for c in model.candidates() if c in CATALOG]
    while cands and len(chosen) < max_effects:
        fits = []
        for c in cands:
            best = None
            for z0 in starts.get(c, (neutral(c),)):
                eff = current_eff + (c,)
                x0 = np.concatenate([current_x, [z0]])
                lo = np.concatenate([lo0, [effect_bounds[e][0] for e in eff]])
                hi = np.concatenate([hi0, [effect_bounds[e][1] for e in eff]])
                x, rss, sd = _fit(model, t, u, y, eff, x0, lo, hi)
                if best is None or rss < best[1]:
                    best = (x, rss, sd)
            assert best is not None
            fits.append((score(current_rss, best[1]), c, best))
        fits.sort(key=lambda f: -f[0])
        if not chosen:
            ranking = [(c, d) for d, c, _ in fits]
        dbic, c, (x, rss, sd) = fits[0]
        if dbic < criterion.min_score:
            break
        val = float(x[-1])
        chosen.append(EffectResult(c, ((c, val),), ((c, float(sd[-1])),), dbic, math.nan,
                                   explanation(c, val)))
        current_eff, current_x = current_eff + (c,), x
        current_rss = rss
        cands = [k for k in cands if k != c]
    k = len(names)
    eff = EffectSet()
    for name, v in zip(current_eff, current_x[k:], strict=True):
        eff = eff.with_effect(name, float(v))
    y_nom = model.simulate(x_nom[:k], EffectSet(), t, u)
    y_fin = model.simulate(current_x[:k], eff, t, u)
    final = tuple(zip(names, (float(v) for v in current_x[:k]), strict=True)) + tuple(
        (e, float(v)) for e, v in zip(current_eff, current_x[k:], strict=True))
    return GenericDiagnosis(tuple(zip(names, (float(v) for v in x_nom), strict=True)), final,
                            tuple(chosen), tuple(ranking), nrmse(y, y_nom), nrmse(y, y_fin), y,
                            y_nom, y_fin)
