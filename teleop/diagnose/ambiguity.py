"""Effects the data given cannot tell apart, and the experiment that would separate them.

Two candidates are indistinguishable on a recording when the runner-up's score is within the
selection rule's own threshold of the chosen effect's (:mod:`teleop.diagnose.criterion`): the
data hold no strong evidence for one over the other.  The report then names both and the
experiment that separates them (from the physics of the pair, not from the recording).
"""

from __future__ import annotations

from teleop.diagnose.criterion import DEFAULT, Criterion

SEPARATE: dict[frozenset[str], str] = {
    frozenset({"dead_time", "actuator_lag"}):
        "a fast step or chirp well above 1/lag, from rest (a delay shifts the whole response, a "
        "lag rounds its start)",
    frozenset({"dead_time", "series_compliance"}):
        "a chirp through the resonance the series spring adds (a delay adds phase at every "
        "frequency, a spring a peak)",
    frozenset({"actuator_gain", "actuator_saturation"}):
        "several effort levels, small and large (a cap only acts on the large ones)",
    frozenset({"coulomb_friction", "stiction"}):
        "slow ramps through velocity reversals (breakaway exceeds sliding friction only near "
        "rest)",
    frozenset({"coulomb_friction", "asymmetric_friction"}):
        "motion of equal size in both directions at several speeds",
    frozenset({"asymmetric_friction", "sensor_offset"}):
        "holds at several positions approached from both sides (an offset is the same at all, "
        "direction-dependent friction changes with the approach)",
    frozenset({"coulomb_friction", "backlash"}):
        "small reversals with a sensor on the load side (play stalls the reading, friction "
        "stops the load)",
    frozenset({"actuator_gain", "coulomb_friction"}):
        "several effort levels (friction is a constant offset of the effort, gain a ratio)",
    frozenset({"actuator_gain", "nonlinear_stiffness"}):
        "static holds at several efforts (a gain scales every deflection, a cubic spring only "
        "the large ones)",
}


def ambiguous(chosen: str, ranking: list[tuple[str, float]] | tuple[tuple[str, float], ...],
              criterion: Criterion = DEFAULT) -> list[str]:
    """Report lines for candidates within ``min_score`` of ``chosen`` (ranking: name, score)."""
    scores = dict(ranking)
    if chosen not in scores:
        return []
    out = []
    for name, s in ranking:
        if name == chosen or s < criterion.min_score:
            continue
        if scores[chosen] - s < criterion.min_score:
            how = SEPARATE.get(frozenset({chosen, name}),
                               "a recording where only one of them acts (different input kind "
                               "or amplitude)")
            out.append(f"cannot tell {chosen} from {name} on this recording (scores "
                       f"{scores[chosen]:.0f} vs {s:.0f}); to separate them: {how}")
    return out
