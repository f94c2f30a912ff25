"""Physics outside the catalog: propose library terms where the chosen effects leave a residual.

When the output-error residual after the catalog effects stays above the noise:

1. the **force-domain residual** of the fitted model (inverse dynamics on the filtered,
   differentiated position, :func:`equation_error.model_equation_error`) is regressed on the
   typed library (:mod:`teleop.diagnose.library`); a term kind with a structural constant
   (wavenumber, delay) is represented by its best constant on a grid;
2. **sequentially thresholded least squares** (STLSQ) keeps the terms whose share of the
   residual is at least ``STLSQ_SHARE`` (columns standardised; refitted after every cut);
3. each surviving term (a sin/cos pair is one term) is added to the nominal **simulation**
   (coefficients, and a pair's wavenumber, fitted by output error) and accepted only by the one
   selection rule (:mod:`teleop.diagnose.criterion`: score, a scanned constant counting as one
   more parameter, and held-out gain);
4. with terms accepted, the catalog effects are selected again on top of nominal + terms (not at
   all when these leave only noise): a catalog effect that was only standing in for
   out-of-catalog physics is not named.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from teleop.diagnose import engine
from teleop.diagnose.axis_model import Array
from teleop.diagnose.ee_filter import EESignals, _filt
from teleop.diagnose.equation_error import ee_rows, model_equation_error
from teleop.diagnose.fit import NUMERIC_FAILURES, FitData, ModelFit, build, simulate
from teleop.diagnose.library import PREFIX, WAVE, Term, column, resolve
from teleop.diagnose.multistart import fit_best, restarts
from teleop.diagnose.results import EffectResult, ProposedTerm
from teleop.diagnose.select import OEPath, select_oe

STLSQ_SHARE = 0.1
DELAYS_S = (0.005, 0.01, 0.02, 0.05, 0.1)
CHUNK = 32   # groups filtered per call (memory: 64 columns x the recording)
STEP_CHECK = 8  # the simulation step checked against one this many times finer


def _cols(sig: EESignals, group: tuple[Term, ...]) -> Array:
    return _filt(np.column_stack([column(t, sig.t, sig.x, sig.v, sig.u) for t in group]),
                 sig.fs_hz, sig.cutoff_hz)


def _best(sig: EESignals, e: Array, groups: list[tuple[Term, ...]]) -> tuple[Term, ...]:
    """The group of a scanned family that explains most of ``e``."""
    rows = ee_rows(sig)
    best, best_g = math.inf, groups[0]
    for i, g in enumerate(groups):
        if i % CHUNK == 0:   # filter CHUNK groups' columns in one call
            chunk = groups[i: i + CHUNK]
            filtered = _cols(sig, tuple(t for h in chunk for t in h))[rows]
            j = 0
        a = filtered[:, j: j + len(g)]
        j += len(g)
        c, *_ = np.linalg.lstsq(a, e[rows], rcond=None)
        rss = float(np.sum((e[rows] - a @ c) ** 2))
        if rss < best:
            best, best_g = rss, g
    return best_g


def candidate_groups(sig: EESignals, e: Array) -> list[tuple[Term, ...]]:
    """One representative of every library family for residual ``e``."""
    x = sig.x[ee_rows(sig)]
    span = float(np.ptp(x)) or 1.0
    noise = float(np.std(np.diff(sig.x))) or 1e-6
    w_lo, w_hi = 3 * math.pi / span, min(0.3 / noise, 200 * math.pi / span)
    dw = math.pi / (2 * span)
    groups: list[tuple[Term, ...]] = []
    if w_hi > w_lo:
        def pair(w: float) -> tuple[Term, ...]:
            return Term("sin", float(w)), Term("cos", float(w))
        w0 = _best(sig, e, [pair(w) for w in np.arange(w_lo, w_hi, dw)])[0].const
        groups.append(_best(sig, e, [pair(w) for w in w0 + np.linspace(-dw, dw, 9)]))
    groups += [(Term(k),) for k in ("vabsv", "v3", "v2", "x2")]  # x^3: catalog's cubic spring
    if sig.u is not None:
        dur = float(sig.t[-1] - sig.t[0])
        groups.append(_best(sig, e, [(Term("udelay", d),) for d in DELAYS_S if d < dur / 4]))
    return groups


def stlsq(a: Array, b: Array, owner: list[int], share: float = STLSQ_SHARE,
          iters: int = 10) -> Array:
    """Sequentially thresholded least squares with grouped columns (``owner[j]``: the group
    of column ``j``): drop every group whose contribution (rms of its fitted part) is below
    ``share`` of the rms of ``b``, refit on the rest, until nothing changes."""
    scale = np.maximum(np.sqrt(np.mean(a ** 2, axis=0)), 1e-300)
    an = a / scale
    keep = np.ones(a.shape[1], bool)
    coef = np.zeros(a.shape[1])
    floor = share * float(np.sqrt(np.mean(b ** 2)))
    for _ in range(iters):
        coef[:] = 0.0
        if not keep.any():
            break
        c, *_ = np.linalg.lstsq(an[:, keep], b, rcond=None)
        coef[keep] = c
        new = keep.copy()
        for g in set(owner):
            idx = [j for j, o in enumerate(owner) if o == g]
            part = an[:, idx] @ coef[idx]
            if float(np.sqrt(np.mean(part ** 2))) < floor:
                new[idx] = False
        if (new == keep).all():
            break
        keep = new
    return coef / scale


def ranked_terms(sig: EESignals, e: Array) -> list[tuple[tuple[Term, ...], tuple[float, ...],
                                                      float]]:
    """Library groups STLSQ keeps for residual ``e``, largest contribution first."""
    groups = candidate_groups(sig, e)
    rows = ee_rows(sig)
    cols = [_cols(sig, g)[rows] for g in groups]
    owner = [i for i, g in enumerate(groups) for _ in g]
    a = np.column_stack(cols)
    coef = stlsq(a, e[rows], owner)
    out = []
    j = 0
    for g, c in zip(groups, cols, strict=True):
        cg = coef[j: j + len(g)]
        j += len(g)
        if np.any(cg != 0):
            out.append((g, tuple(float(v) for v in cg), float(np.sqrt(np.mean((c @ cg) ** 2)))))
    return sorted(out, key=lambda r: -r[2])


def propose(path: OEPath, nom: ModelFit, final: ModelFit
            ) -> tuple[ModelFit, tuple[ProposedTerm, ...]]:
    """Library terms for the force-domain residual of ``final`` (the model with the chosen
    catalog effects), each judged by the rule against the nominal model ``nom`` with the terms
    accepted before it; returns that model and the terms (``final`` and none when nothing
    passes)."""
    data, nominal, sig, opts = path.data, path.nominal, path.sig, path.opts
    rule = engine.Rule(criterion=opts.criterion)
    p, eff = build(final.names, final.theta, data)
    e = model_equation_error(sig, p, eff)    # J a - modelled efforts: the effort it lacks
    current = nom
    accepted: list[ProposedTerm] = []
    for group, coefs, _ in ranked_terms(sig, e):
        start = {**current.as_dict(), **{t.key: c for t, c in zip(group, coefs, strict=True)}}
        if group[0].kind == "sin":   # its wavenumber is refined by the simulation fit
            start[f"{WAVE}{group[0].const:.6g}"] = group[0].const
        try:
            f = fit_best(data, nominal, restarts(start), current.effects, opts.max_nfev * 4)
        except NUMERIC_FAILURES:
            continue
        key = group[0].key
        step, _ = engine.accept_first(path, current,
                                      [(engine.score(path, current, f, rule), key, f)], rule)
        if step is not None:
            accepted.append(ProposedTerm(tuple(t.key for t in group), coefs,
                                         step.verdict.score, step.verdict.holdout_gain))
            current = f
    if not accepted:
        return final, ()
    return current, tuple(accepted)


def final_terms(fit: ModelFit, accepted: tuple[ProposedTerm, ...]) -> tuple[ProposedTerm, ...]:
    """The accepted terms with their coefficients (and fitted wavenumbers) as in ``fit``."""
    resolved = dict(zip((k for k in fit.names if k.startswith(PREFIX)),
                        (k for k, _ in resolve(fit.as_dict())), strict=True))
    return tuple(ProposedTerm(tuple(resolved[k] for k in t.keys),
                              tuple(fit.value(k) for k in t.keys), t.score, t.holdout_gain)
                 for t in accepted)


def step_error(data: FitData, f: ModelFit, finer: int = STEP_CHECK) -> float:
    """The output-error simulation's own error for the fitted model ``f``: rms of its change
    when the integration sub-step is made ``finer`` times smaller (the input held per sample
    either way).  What the fit leaves within this (and the noise) the simulation itself may
    have made: no library term is proposed for it.  The clean closed-loop drive of
    ``indep_axis.make_closed_loop(3, 0, 0)`` (friction in the model, an integrating plant
    driven by the logged force) leaves 1.87x its noise, and its simulation moves 6.5x the
    noise at an 8x finer step: ``sin(189 x)`` was proposed there (held-out 69 %).  Cogging
    cases leave 18-62x the noise against a step error of 0-11x."""
    y1 = simulate(f.names, f.theta, data)
    y2 = simulate(f.names, f.theta, replace(data, max_dt_s=data.max_dt_s / finer))
    d = y1 - y2
    return float(np.sqrt(np.mean(d ** 2))) if np.all(np.isfinite(d)) else math.inf


def select_with_library(path: OEPath, nom: ModelFit
                        ) -> tuple[ModelFit, list[EffectResult], list[tuple[str, float]],
                                   tuple[ProposedTerm, ...], tuple[str, ...]]:
    """Catalog selection (:func:`select.select_oe`); then, while the residual stays above the
    noise and the simulation's own error (:func:`step_error`), library terms
    (:func:`propose`) and the catalog selected again on top of them, unless they leave only
    noise (``select_oe``'s own stopping rule)."""
    opts, noise = path.opts, path.noise
    final, chosen, ranking, amb = select_oe(path, nom)
    rms = math.sqrt(final.rss / final.n)
    if rms < opts.noise_factor * noise or rms < opts.noise_factor * math.hypot(
            noise, step_error(path.data, final)):
        return final, chosen, ranking, (), amb
    base, proposed = propose(path, nom, final)
    if not proposed:
        return final, chosen, ranking, (), amb
    final, chosen, amb = base, [], ()
    if math.sqrt(base.rss / base.n) >= opts.noise_factor * noise:
        final, chosen, _, amb = select_oe(path, base)
    return final, chosen, ranking, final_terms(final, proposed), amb
