"""The one selection engine of ``teleop diagnose``: greedy forward selection of catalog effects
under the one rule (:mod:`teleop.diagnose.criterion`), for every model path (axis output-error
:mod:`~teleop.diagnose.select`, equation-error :mod:`~teleop.diagnose.select_ee`, the static
finger :mod:`~teleop.diagnose.generic` and the dynamic finger :mod:`~teleop.diagnose.select_sim`).

A path says only how it fits (a :class:`Path`): the candidates fitted on top of the current
model, a fit's training residual, the held-out gain of a candidate and when what is left is the
floor.  The engine ranks the candidates by the rule's score, walks them best first, accepts the
first the rule accepts (score, then held-out gain), and records why the others were refused and
which runner-up the data cannot tell from the chosen effect (:mod:`teleop.diagnose.ambiguity`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Generic, Protocol, TypeVar

from teleop.diagnose.ambiguity import ambiguous_fits
from teleop.diagnose.criterion import DEFAULT, Criterion, Verdict, judge, score_of
from teleop.diagnose.fit import NUMERIC_FAILURES

F = TypeVar("F")


class Path(Protocol[F]):
    """What the engine needs of one model path (``F``: the path's fit object)."""

    def rss(self, f: F) -> float:
        """Training residual sum of squares."""

    def residual(self, f: F) -> Any:
        """Training residual (its effective sample size weighs the score)."""

    def k_added(self, base: F, f: F) -> int:
        """Parameters ``f`` has beyond ``base``."""

    def fit_candidates(self, current: F, names: tuple[str, ...]) -> list[tuple[str, F]]:
        """Candidates ``names`` each fitted on top of ``current`` (failures left out)."""

    def holdout(self, current: F, name: str, f: F) -> tuple[float, bool]:
        """(held-out gain of ``f`` over ``current``, whether the held-out part is
        informative); gain nan: no held-out data."""

    def at_floor(self, current: F, n_chosen: int) -> bool:
        """Whether what ``current`` leaves is the floor (noise): selection stops."""


def own_share(path: Any, current: F, name: str, f: F) -> F | None:
    """``f`` with the effect ``name`` removed and everything else held at ``f``'s values, if
    the path can say (a method ``without(current, name, f)``); None otherwise.

    A joint fit refits the nominal parameters with the effect, and may find them a better
    optimum than the nominal fit did; the gain is then the nominal's, not the effect's (on a
    live dynamixel recording a 0.1 rad sensor offset scored 10.8 while the refit moved the
    motor gain and friction to their bounds: with those held, the offset itself was worth a
    1 % RSS change).  So an effect must carry the rule's score on its own too.  The dynamic
    finger (its position-periodic term too), axis output-error and static paths say; the
    equation-error path need not (its nominal is a linear least-squares fit, already at its
    optimum), nor the axis path's library terms."""
    without = getattr(path, "without", None)
    return None if without is None else without(current, name, f)


@dataclass(frozen=True, slots=True)
class Step(Generic[F]):
    """One accepted effect."""

    name: str
    fit: F
    verdict: Verdict


@dataclass(frozen=True, slots=True)
class Selection(Generic[F]):
    """What the engine chose, and why."""

    final: F
    steps: tuple[Step[F], ...]
    ranking: tuple[tuple[str, float], ...]     # first step: (effect, score), best first
    rejected: tuple[tuple[str, str], ...]      # (effect, why) of refused candidates
    ambiguous: tuple[str, ...] = ()            # report lines: pairs the data cannot separate


@dataclass(frozen=True, slots=True)
class Rule:
    """The rule's data-side settings a path states (the thresholds are the criterion's)."""

    noise: float | None = None       # known noise (e.g. an instrument); None: estimated
    n_eff: float | None = None       # independent samples, when the path knows (static points)
    criterion: Criterion = DEFAULT


RULE = Rule()


def score(path: Path[F], base: F, f: F, rule: Rule = RULE) -> float:
    """The rule's penalised likelihood gain of ``f`` over ``base``."""
    return score_of(path.rss(base), path.rss(f), path.residual(f), path.k_added(base, f),
                    rule.noise, rule.n_eff)[0]


def accept_first(path: Path[F], current: F, ranked: Sequence[tuple[float, str, F]],
                 rule: Rule = RULE) -> tuple[Step[F] | None, list[tuple[str, str]]]:
    """Walk ``ranked`` (score, name, fit; best first): the first candidate the rule accepts,
    and (name, why) of those refused before it.  A candidate under the score threshold is
    refused without its held-out fit (so are all after it)."""
    rejected: list[tuple[str, str]] = []
    crit = rule.criterion
    for s, name, f in ranked:
        if s < crit.min_score:
            rejected.append((name, f"score {s:.1f} < {crit.min_score:g}"))
            continue
        alone = own_share(path, current, name, f)
        if alone is not None:
            own = score(path, alone, f, rule)
            if own < crit.min_score:
                rejected.append((name, f"score {s:.1f}, but {own:.1f} < {crit.min_score:g} "
                                       "for the effect itself (the rest of the fit held): "
                                       "the gain is the refitted nominal's"))
                continue
        try:
            gain, informative = path.holdout(current, name, f)
        except NUMERIC_FAILURES:
            rejected.append((name, "held-out fit failed numerically"))
            continue
        v = judge(path.rss(current), path.rss(f), path.residual(f), path.k_added(current, f),
                  gain, informative, rule.noise, crit, rule.n_eff)
        if v.accepted:
            return Step(name, f, v), rejected
        rejected.append((name, v.why))
    return None, rejected


def forward(path: Path[F], start: F, names: Sequence[str], max_effects: int,
            rule: Rule = RULE,
            rank: Callable[[F, list[tuple[float, str, F]]], list[tuple[float, str, F]]]
            | None = None) -> Selection[F]:
    """Greedy forward selection from ``start`` over ``names``: fit every remaining candidate,
    rank by score, accept the first the rule accepts, repeat until none is accepted, the
    floor is reached or ``max_effects`` are chosen.  ``rank`` may re-fit the ranked list
    (e.g. refine the leading candidates) before the walk; the engine re-sorts it."""
    current = start
    steps: list[Step[F]] = []
    ranking: tuple[tuple[str, float], ...] = ()
    rejected: list[tuple[str, str]] = []
    amb: tuple[str, ...] = ()
    while len(steps) < max_effects and not path.at_floor(current, len(steps)):
        remaining = tuple(n for n in names if n not in {s.name for s in steps})
        if not remaining:
            break
        fits = [(score(path, current, f, rule), n, f)
                for n, f in path.fit_candidates(current, remaining)]
        fits.sort(key=lambda x: -x[0])
        if rank is not None:
            fits = sorted(rank(current, fits), key=lambda x: -x[0])
        if not steps:
            ranking = tuple((n, s) for s, n, _ in fits)
        step, refused = accept_first(path, current, fits, rule)
        rejected += refused
        if step is None:
            break
        if not steps:
            amb = tuple(ambiguous_fits(
                step.name, path.residual(step.fit),
                [(n, path.rss(f), path.k_added(current, f), s) for s, n, f in fits],
                rule.criterion))
        steps.append(step)
        current = step.fit
    return Selection(current, tuple(steps), ranking, tuple(rejected), amb)
