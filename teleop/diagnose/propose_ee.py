"""Physics outside the catalog on the equation-error (closed-loop) path.

The same typed library and sparse regression as the output-error path
(:func:`teleop.diagnose.propose.ranked_terms`), on the effort residual the equation error
already is: after the catalog effects, the residual ``sum(coef col) - target`` is the effort
the model lacks (``J a = ... + c phi``).  Each kept term is added to the inverse-dynamics
regression (its wavenumber or delay as scanned) and accepted only through the one engine
(:func:`teleop.diagnose.engine.accept_first`: score on the regression rows, a scanned constant
counted as a parameter, and held-out gain on the last 30 % of the recording with both models
fitted on the rest).  With terms accepted, the catalog is selected again on top of nominal +
terms, so a catalog effect that only stood in for the out-of-catalog physics is not named.

Unlike the output-error path, terms are proposed only when no catalog effect is accepted: the
equation error has no held-out *simulation* to weigh a term against a catalog effect of the
same shape, and no known noise floor to say the residual is physics (a propagated encoder-noise
floor put a cogging residual at 1.7x and a Coulomb-law mismatch at 7.7x: no threshold separates
them).
"""

from __future__ import annotations

from teleop.diagnose import engine
from teleop.diagnose.candidates import Scales
from teleop.diagnose.equation_error import EEFit, EESignals, ee_fit
from teleop.diagnose.fit import NUMERIC_FAILURES
from teleop.diagnose.model import AxisNominal
from teleop.diagnose.propose import ranked_terms
from teleop.diagnose.results import DiagnoseOptions, EffectResult, ProposedTerm
from teleop.diagnose.select import _ee_grids
from teleop.diagnose.select_ee import EEPath, EEState, catalog_ee


def propose_ee(path: EEPath, nom: EEState, final: EEState, opts: DiagnoseOptions
               ) -> tuple[EEState, tuple[ProposedTerm, ...]]:
    """Library terms for the effort residual of ``final``, each judged by the engine against
    ``nom`` with the terms accepted before it; that model and the terms."""
    rule = engine.Rule(criterion=opts.criterion)
    current = nom
    accepted: list[ProposedTerm] = []
    for group, _, _ in ranked_terms(path.sig, final.fit.residual):
        terms = current.terms + group
        try:
            f = EEState(ee_fit(path.sig, path.nominal, current.base, path.fixed_inertia, terms),
                        current.base, terms)
        except NUMERIC_FAILURES:
            continue
        step, _ = engine.accept_first(
            path, current, [(engine.score(path, current, f, rule), group[0].key, f)], rule)
        if step is not None:
            accepted.append(ProposedTerm(tuple(t.key for t in group),
                                         tuple(f.fit.get(t.key) for t in group),
                                         step.verdict.score, step.verdict.holdout_gain))
            current = f
    return current, tuple(accepted)


def select_ee_with_library(sig: EESignals, nominal: AxisNominal, opts: DiagnoseOptions,
                           names: tuple[str, ...], fixed_inertia: float, scales: Scales
                           ) -> tuple[EEFit, EEFit, list[EffectResult], list[tuple[str, float]],
                                      tuple[ProposedTerm, ...], tuple[str, ...]]:
    """Catalog selection on the equation error; then library terms; then, with terms, the
    catalog again on top of them.  Returns the nominal and final fits, the effects, the first
    ranking, the proposed terms and the ambiguity notes."""
    path = EEPath(sig, nominal, fixed_inertia, _ee_grids(scales))
    nom = EEState(ee_fit(sig, nominal, {}, fixed_inertia), {})
    final, chosen, ranking, amb = catalog_ee(path, nom, opts, names)
    if chosen:
        # the effort residual has no simulation to check a term against catalog effects, nor a
        # known noise floor: terms only where the catalog explains nothing (measured: with a
        # Coulomb law sharper than the model's, v|v| and v^3 were kept next to the Coulomb
        # level and pulled it from 3.0 to 2.5)
        return nom.fit, final.fit, chosen, ranking, (), amb
    with_terms, proposed = propose_ee(path, nom, final, opts)
    if not proposed:
        return nom.fit, final.fit, chosen, ranking, (), amb
    final, chosen, _, amb = catalog_ee(path, with_terms, opts, names)
    terms = tuple(ProposedTerm(p.keys, tuple(final.fit.get(k) for k in p.keys), p.score,
                               p.holdout_gain) for p in proposed)
    return nom.fit, final.fit, chosen, ranking, terms, amb
