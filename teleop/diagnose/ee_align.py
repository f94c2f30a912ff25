"""The input's sample alignment on the equation-error path.

A recording does not say whether an input sample is held until the next one or passes through
a continuous signal, nor whether it was logged at the start or the end of its period (the
output-error path fits the same nuisance, ``input_shift``, :func:`teleop.diagnose.axis_model.
input_effort`).  On the inverse dynamics a one-sample misalignment leaves an effort residual of
about ``dt x du/dt``: on a stiff PD loop more than the effort noise, and structured, so library
terms (a delayed input) fit it (measured, docs/diagnose-results.md).  The alignment is chosen
on a grid within one raw sample period either way, as the one whose fit leaves the least
residual: first under the nominal model, then once more under the model the selection chose
(a missing effect biases the first choice: on an independent closed-loop drive with
direction-dependent friction and a continuous controller the nominal chose -1 sample, the
model with the friction 0, the truth); when that moves it, the selection runs again on the
input aligned so.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TypeVar

import numpy as np

from teleop.diagnose.axis_model import delayed
from teleop.diagnose.ee_filter import concat_ee, ee_signals
from teleop.diagnose.ee_noise import Raw
from teleop.diagnose.equation_error import EEFit, ee_fit, fit_effects
from teleop.diagnose.model import AxisNominal

R = TypeVar("R")
ALIGN_SAMPLES = tuple(float(k) for k in np.linspace(-1.0, 1.0, 9))


def shifted(raw: Sequence[Raw], shift_s: float) -> list[Raw]:
    """The recordings with their input delayed by ``shift_s`` (negative: a lead)."""
    return [(t, None if u is None else delayed(t, u, shift_s), y) for t, u, y in raw]


def align_input(raw: Sequence[Raw], nominal: AxisNominal, fixed_inertia: float,
                like: EEFit | None = None) -> tuple[float, list[Raw]]:
    """(alignment in s, the aligned recordings): the delay on :data:`ALIGN_SAMPLES` raw
    sample periods whose equation-error fit (the nominal, or the effects and terms of
    ``like``) leaves the least residual."""
    effects = {} if like is None else fit_effects(like, nominal)
    terms = () if like is None else like.terms
    if raw[0][1] is None:
        return 0.0, list(raw)
    dt = float(np.median(np.diff(raw[0][0])))
    best_rss, best = np.inf, 0.0
    for k in ALIGN_SAMPLES:
        cand = shifted(raw, k * dt)
        sig = concat_ee([ee_signals(t, y, u) for t, u, y in cand])
        rss = ee_fit(sig, nominal, effects, fixed_inertia, terms).rss
        if rss < best_rss:
            best_rss, best = rss, k * dt
    return best, shifted(raw, best)


def aligned_selection(raw: Sequence[Raw], nominal: AxisNominal, fixed_inertia: float,
                      select: Callable[[list[Raw]], R], final_of: Callable[[R], EEFit]
                      ) -> tuple[float, R]:
    """(alignment in s, ``select``'s result on the aligned recordings): aligned under the
    nominal, then under the chosen model ``final_of(result)``, selected again if that moved
    the alignment."""
    shift, aligned = align_input(raw, nominal, fixed_inertia)
    result = select(aligned)
    shift2, aligned2 = align_input(raw, nominal, fixed_inertia, final_of(result))
    if shift2 != shift:
        shift, result = shift2, select(aligned2)
    return shift, result
