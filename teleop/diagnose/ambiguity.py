"""Effects the data given cannot tell apart, and the experiment that would separate them.

Two candidates are indistinguishable on a recording when the rule's score of the chosen effect
against the runner-up (in the independent samples of the chosen model's residual, slow structure
counted) is under the rule's own threshold (:mod:`teleop.diagnose.criterion`): the data hold no
strong evidence for one over the other.  The report then names both and the
experiment that separates them (from the physics of the pair, not from the recording).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from teleop.diagnose.criterion import DEFAULT, Array, Criterion, structured_n
from teleop.diagnose.library import PERIODIC

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
    **{frozenset({PERIODIC, name}):
       "slow moves at constant speed over several periods of the angle, in both directions (a "
       "friction or a play acts the same at every angle, a position-periodic force repeats "
       "with it)"
       for name in ("coulomb_friction", "asymmetric_friction", "stiction", "backlash")},
}


def ambiguous_fits(chosen: str, residual: Array,
                   fits: Sequence[tuple[str, float, int, float]],
                   criterion: Criterion = DEFAULT) -> list[str]:
    """Report lines for the candidates of one step the data cannot tell from ``chosen``.

    ``fits``: (name, training RSS, added parameters, score) of every candidate fitted at that
    step, ``chosen`` among them; ``residual``: the chosen model's training residual.  The
    evidence for ``chosen`` over a runner-up ``b`` is the rule's score of one against the
    other, ``n ln(RSS_b / RSS_chosen) - (k_chosen - k_b) ln n``, with ``n`` the independent
    samples of the chosen model's residual counting its slow structure
    (:func:`criterion.structured_n`): where the chosen effect leaves structure the model
    lacks, a small difference in fit is not evidence for one effect over the other.  A pair
    is reported when that evidence is under the rule's ``min_score`` and the runner-up passes
    the score itself.
    """
    by = {n: (rss, k) for n, rss, k, _ in fits}
    if chosen not in by:
        return []
    rss_a, k_a = by[chosen]
    n_s = structured_n(residual)
    out = []
    for name, rss_b, k_b, s_b in fits:
        if name == chosen or not s_b >= criterion.min_score or not math.isfinite(rss_b):
            continue
        evidence = (n_s * math.log(rss_b / rss_a) if rss_a > 0 else math.inf) - (
            k_a - k_b) * math.log(max(n_s, math.e))
        if evidence < criterion.min_score:
            how = SEPARATE.get(frozenset({chosen, name}),
                               "a recording where only one of them acts (different input kind "
                               "or amplitude)")
            out.append(f"cannot tell {chosen} from {name} on this recording (evidence for "
                       f"{chosen} {evidence:.1f} < {criterion.min_score:g}, in "
                       f"{n_s:.0f} independent samples); to separate them: {how}")
    return out
