"""Physics outside the catalog on the equation-error (closed-loop) path.

The same typed library and sparse regression as the output-error path
(:func:`teleop.diagnose.propose.ranked_terms`), on the effort residual the equation error
already is: the residual ``sum(coef col) - target`` is the effort the model lacks (``J a = ... +
c phi``).  Library terms and catalog effects compete **in the same engine call by the same
rule** (:func:`teleop.diagnose.engine.forward` through
:func:`teleop.diagnose.select_ee.catalog_ee`: score on the regression rows, a scanned constant
counted as a parameter, held-out gain on the last 30 % of the recording with both models fitted
on the rest): at every step until a catalog effect is accepted, the library groups STLSQ keeps
for the current residual are candidates beside the catalog effects, whenever that residual stays
above the noise (``noise_factor`` x the effort residual's own floor,
:mod:`teleop.diagnose.ee_noise`).  Once a catalog effect is named, the catalog selection goes on
without the library; after it, the library is offered once more **on what the catalog effects
leave** (they stay in the model, and the terms are judged by the same engine and rule on top of
them), while that residual stays above the noise.  With terms accepted, the catalog effects are
checked again with the terms in the model (the rule's score, as the output-error path's backward
elimination): one the terms make redundant stood in for them and is not named.

Why this shape (measured, docs/diagnose-results.md): with terms proposed only when no catalog
effect was accepted, 4 of 6 cogging drives named a 0.01-0.04 s ``dead_time`` (score 12-38)
that stood in for the cogging unchallenged; the periodic term scores far higher on them and now
wins the first step, and the dead time is then refused on top of it.  A cogging behind a larger
catalog effect (a direction-dependent Coulomb level) was left in the residual with a warning;
the stage after the catalog names it.  That stage kept ``u(t - 0.1 s)`` and ``v|v|`` next to
``coulomb_friction`` on a PD drive whose physics is all in the catalog, while the equation
error there was 16x its noise: the fit's own inconsistencies (the input filtered once against
position columns filtered twice, the input's sample alignment), fixed in
:mod:`teleop.diagnose.equation_error` and :mod:`teleop.diagnose.ee_align`; the residual there
is now at the noise and the gate closes.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from teleop.diagnose import engine
from teleop.diagnose.candidates import Scales
from teleop.diagnose.ee_filter import EESignals
from teleop.diagnose.equation_error import EE_EFFECTS, EEFit, ee_fit, ee_rows
from teleop.diagnose.fit import NUMERIC_FAILURES
from teleop.diagnose.model import AxisNominal
from teleop.diagnose.propose import ranked_terms
from teleop.diagnose.results import DiagnoseOptions, EffectResult, ProposedTerm
from teleop.diagnose.select import _ee_grids
from teleop.diagnose.select_ee import EEPath, EEState, catalog_ee, effect_result


@dataclass(frozen=True)
class EELibraryPath(EEPath):
    """The equation-error path whose candidates include library terms while no catalog effect
    is named and the residual stays above the noise (``noise_of``: a fit's noise level)."""

    noise_of: Callable[[EEFit], float] | None = None
    noise_factor: float = 1.5
    after_catalog: bool = False   # the second stage: library terms only, on top of the effects

    def above_noise(self, f: EEFit) -> bool:
        if self.noise_of is None:
            return True
        r = f.residual[ee_rows(self.sig)]
        return math.sqrt(float(np.mean(r ** 2))) >= self.noise_factor * self.noise_of(f)

    def fit_candidates(self, current: EEState, names: tuple[str, ...]
                       ) -> list[tuple[str, EEState]]:
        out = [] if self.after_catalog else super().fit_candidates(current, names)
        if (current.base and not self.after_catalog) or not self.above_noise(current.fit):
            return out
        for group, _, _ in ranked_terms(self.sig, current.fit.residual):
            terms = current.terms + group
            try:
                f = ee_fit(self.sig, self.nominal, current.base, self.fixed_inertia, terms)
            except NUMERIC_FAILURES:
                continue
            if math.isfinite(f.bic):
                out.append((group[0].key, EEState(f, current.base, terms)))
        return out


def _recheck(path: EELibraryPath, state: EEState, chosen: list[EffectResult], rule: engine.Rule
             ) -> tuple[EEState, list[EffectResult]]:
    """The catalog effects checked again with the library terms in the model (backward, by
    the rule's score, as the output-error path's elimination): one the terms make redundant
    stood in for physics outside the catalog and is dropped; the others' values as they stand
    in the joint fit."""
    changed = True
    while changed and chosen:
        changed = False
        for c in chosen:
            base = {k: v for k, v in state.base.items() if k != c.name}
            try:
                reduced = EEState(ee_fit(path.sig, path.nominal, base, path.fixed_inertia,
                                         state.terms), base, state.terms)
            except NUMERIC_FAILURES:
                continue  # cannot test this removal: keep the effect
            if engine.score(path, reduced, state, rule) < rule.criterion.min_score:
                state, chosen, changed = reduced, [x for x in chosen if x is not c], True
                break
    return state, [effect_result(c.name, state.fit, c.delta_bic, c.holdout_gain)
                   for c in chosen]


def select_ee_with_library(sig: EESignals, nominal: AxisNominal, opts: DiagnoseOptions,
                           names: tuple[str, ...], fixed_inertia: float, scales: Scales,
                           noise_of: Callable[[EEFit], float] | None = None
                           ) -> tuple[EEFit, EEFit, list[EffectResult], list[tuple[str, float]],
                                      tuple[ProposedTerm, ...], tuple[str, ...]]:
    """Forward selection over catalog effects and library terms (see the module docstring).
    Returns the nominal and final fits, the effects, the first step's ranking of catalog
    effects, the proposed terms (coefficients as in the final fit) and the ambiguity notes."""
    path = EELibraryPath(sig, nominal, fixed_inertia, _ee_grids(scales), noise_of,
                         opts.noise_factor)
    nom = EEState(ee_fit(sig, nominal, {}, fixed_inertia), {})
    sel, chosen, ranking = catalog_ee(path, nom, opts, names)
    steps = sel.steps
    if chosen and len(steps) < opts.max_effects:
        # the library on what the catalog effects leave (they stay in the model), by the
        # same engine and rule
        lib = engine.forward(replace(path, after_catalog=True), sel.final, names,
                             opts.max_effects - len(steps), engine.Rule(criterion=opts.criterion))
        if lib.steps:
            final_state, chosen = _recheck(path, lib.final, chosen,
                                           engine.Rule(criterion=opts.criterion))
            steps = tuple(st for st in steps if st.name not in EE_EFFECTS
                          or st.name in {c.name for c in chosen}) + lib.steps
            sel = replace(sel, final=final_state, steps=steps)
    final = sel.final.fit
    terms, prev = [], nom
    for st in steps:
        if st.name not in EE_EFFECTS:
            keys = tuple(t.key for t in st.fit.terms[len(prev.terms):])
            terms.append(ProposedTerm(keys, tuple(final.get(k) for k in keys),
                                      st.verdict.score, st.verdict.holdout_gain))
        prev = st.fit
    return nom.fit, final, chosen, ranking, tuple(terms), sel.ambiguous
