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
from teleop.diagnose import engine
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


@dataclass(frozen=True)
class _StaticFit:
    effects: tuple[str, ...]
    x: Array
    rss: float
    sd: Array
    residual: Array


def _effect_set(effects: tuple[str, ...], values: Array) -> EffectSet:
    """The catalog effects ``effects`` at ``values``."""
    e = EffectSet()
    for name, v in zip(effects, values, strict=True):
        e = e.with_effect(name, float(v))
    return e


def _fit(model: NominalModel, t: Array, u: Array | None, y: Array, effects: tuple[str, ...],
         start: Array, lo: Array, hi: Array) -> _StaticFit:
    k = len(model.param_names())

    def resid(x: Array) -> Array:
        return model.simulate(x[:k], _effect_set(effects, x[k:]), t, u) - y

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
    return _StaticFit(effects, res.x, float(r @ r), sd, r)


@dataclass(frozen=True)
class StaticPath:
    """Static points for the engine (:mod:`teleop.diagnose.engine`): every candidate fitted from
    each of its start values; no held-out part (the score alone decides)."""

    model: NominalModel
    t: Array
    u: Array | None
    y: Array
    starts: dict[str, tuple[float, ...]]
    effect_bounds: dict[str, tuple[float, float]]

    def rss(self, f: _StaticFit) -> float:
        return f.rss

    def residual(self, f: _StaticFit) -> Array:
        return f.residual

    def k_added(self, base: _StaticFit, f: _StaticFit) -> int:
        return len(f.effects) - len(base.effects)

    def at_floor(self, current: _StaticFit, n_chosen: int) -> bool:
        return False

    def holdout(self, current: _StaticFit, name: str, f: _StaticFit) -> tuple[float, bool]:
        return math.nan, True   # a few static points: nothing to hold out

    def without(self, current: _StaticFit, name: str, f: _StaticFit) -> _StaticFit:
        """``f`` with ``name`` removed, the rest held (:func:`engine.own_share`)."""
        k = len(self.model.param_names())
        keep = [i for i, e in enumerate(f.effects) if e != name]
        effects = tuple(f.effects[i] for i in keep)
        x = np.concatenate([f.x[:k], f.x[k:][keep]])
        r = self.model.simulate(x[:k], _effect_set(effects, x[k:]), self.t, self.u) - self.y
        return _StaticFit(effects, x, float(r @ r), f.sd, r)

    def fit_candidates(self, current: _StaticFit, names: tuple[str, ...]
                       ) -> list[tuple[str, _StaticFit]]:
        lo0, hi0 = self.model.bounds()
        out = []
        for c in names:
            eff = current.effects + (c,)
            lo = np.concatenate([lo0, [self.effect_bounds[e][0] for e in eff]])
            hi = np.concatenate([hi0, [self.effect_bounds[e][1] for e in eff]])
            fits = [_fit(self.model, self.t, self.u, self.y, eff,
                         np.concatenate([current.x, [z0]]), lo, hi)
                    for z0 in self.starts.get(c, (neutral(c),))]
            out.append((c, min(fits, key=lambda f: f.rss)))
        return out


def diagnose_model(model: NominalModel, t: Array, u: Array | None, y: Array, noise_std: float,
                   starts: dict[str, tuple[float, ...]], effect_bounds: dict[str, tuple[float,
                                                                                         float]],
                   criterion: crit.Criterion = crit.DEFAULT, max_effects: int = 2
                   ) -> GenericDiagnosis:
    """Fit the nominal model, then select effects by the engine (known noise; the static
    points are independent equilibria, so ``n_eff = n``)."""
    n = len(y)
    names = model.param_names()
    lo0, hi0 = model.bounds()
    nom = _fit(model, t, u, y, (), model.initial(), lo0, hi0)
    path = StaticPath(model, t, u, y, starts, effect_bounds)
    sel = engine.forward(path, nom, tuple(c for c in model.candidates() if c in CATALOG),
                         max_effects, engine.Rule(noise=noise_std, n_eff=float(n),
                                                  criterion=criterion))
    chosen = []
    for st in sel.steps:
        val = float(st.fit.x[-1])
        chosen.append(EffectResult(st.name, ((st.name, val),),
                                   ((st.name, float(st.fit.sd[-1])),), st.verdict.score,
                                   math.nan, explanation(st.name, val)))
    x_nom, current_x, current_eff = nom.x, sel.final.x, sel.final.effects
    k = len(names)
    eff = EffectSet()
    for name, v in zip(current_eff, current_x[k:], strict=True):
        eff = eff.with_effect(name, float(v))
    y_nom = model.simulate(x_nom[:k], EffectSet(), t, u)
    y_fin = model.simulate(current_x[:k], eff, t, u)
    final = tuple(zip(names, (float(v) for v in current_x[:k]), strict=True)) + tuple(
        (e, float(v)) for e, v in zip(current_eff, current_x[k:], strict=True))
    return GenericDiagnosis(tuple(zip(names, (float(v) for v in x_nom), strict=True)), final,
                            tuple(chosen), sel.ranking, nrmse(y, y_nom), nrmse(y, y_fin), y,
                            y_nom, y_fin)
