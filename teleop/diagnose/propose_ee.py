"""Physics outside the catalog on the equation-error (closed-loop) path.

The same typed library and sparse regression as the output-error path
(:func:`teleop.diagnose.propose.ranked_terms`), on the effort residual the equation error
already is: the residual ``sum(coef col) - target`` is the effort the model lacks
(``J a = ... + c phi``).  Library terms and catalog effects compete **in the same engine call
by the same rule** (:func:`teleop.diagnose.engine.forward` through
:func:`teleop.diagnose.select_ee.catalog_ee`: score on the regression rows, a
scanned constant counted as a parameter, held-out gain on the last 30 % of the recording with
both models fitted on the rest): at every step until a catalog effect is accepted, the library
groups STLSQ keeps for the current residual are candidates beside the catalog effects, whenever
that residual stays above the noise (``noise_factor`` x the effort residual's own floor,
:mod:`teleop.diagnose.ee_noise`).  Once a catalog effect is named, the library is not offered
again.

Why this shape (measured, docs/diagnose-results.md): with terms proposed only when no catalog
effect was accepted, 4 of 6 cogging drives named a 0.01-0.04 s ``dead_time`` (score 12-38)
that stood in for the cogging unchallenged; the periodic term scores far higher on them and now
wins the first step, and the dead time is then refused on top of it.  With terms offered at
every step, a Coulomb drive got ``v^3`` and ``v|v|`` next to ``coulomb_friction`` (its level
pulled from 2.9 to 2.5): the equation error's filtered sign law leaves a structured residual
near reversals that those terms fit; the Coulomb effect scores far higher than any term at the
first step, so here the library stops once it is named, and the unexplained-residual warning
says what is left.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from teleop.diagnose.candidates import Scales
from teleop.diagnose.equation_error import EE_EFFECTS, EEFit, EESignals, ee_fit, ee_rows
from teleop.diagnose.fit import NUMERIC_FAILURES
from teleop.diagnose.model import AxisNominal
from teleop.diagnose.propose import ranked_terms
from teleop.diagnose.results import DiagnoseOptions, EffectResult, ProposedTerm
from teleop.diagnose.select import _ee_grids
from teleop.diagnose.select_ee import EEPath, EEState, catalog_ee


@dataclass(frozen=True)
class EELibraryPath(EEPath):
    """The equation-error path whose candidates include library terms while no catalog effect
    is named and the residual stays above the noise (``noise_of``: a fit's noise level)."""

    noise_of: Callable[[EEFit], float] | None = None
    noise_factor: float = 1.5

    def above_noise(self, f: EEFit) -> bool:
        if self.noise_of is None:
            return True
        r = f.residual[ee_rows(self.sig)]
        return math.sqrt(float(np.mean(r ** 2))) >= self.noise_factor * self.noise_of(f)

    def fit_candidates(self, current: EEState, names: tuple[str, ...]
                       ) -> list[tuple[str, EEState]]:
        out = super().fit_candidates(current, names)
        if current.base or not self.above_noise(current.fit):
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
    final = sel.final.fit
    terms, prev = [], nom
    for st in sel.steps:
        if st.name not in EE_EFFECTS:
            keys = tuple(t.key for t in st.fit.terms[len(prev.terms):])
            terms.append(ProposedTerm(keys, tuple(final.get(k) for k in keys),
                                      st.verdict.score, st.verdict.holdout_gain))
        prev = st.fit
    return nom.fit, final, chosen, ranking, tuple(terms), sel.ambiguous
