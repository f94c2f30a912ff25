"""The one effect-selection rule of ``teleop diagnose`` (every model path uses it).

An effect (``k`` added parameters) is accepted when

1. its **penalised likelihood gain** is at least ``min_score``::

       score = -2 delta log L - k ln(n_eff)
       -2 delta log L = n_eff ln(RSS_0 / RSS_1)                    (noise estimated)
                      = (RSS_0 - RSS_1) / sigma^2 * n_eff / n      (noise known, e.g. a gauge)

   with an *effective sample size* ``n_eff = n (1 - rho) / (1 + rho)`` from the lag-1
   autocorrelation ``rho`` of the fast part of the augmented model's residual (coloured or
   oversampled noise counts as fewer independent samples); and
2. its **held-out gain** (relative error reduction on data the fit did not see) is at least
   ``min_holdout_gain``. When the held-out part is already explained to the noise by the model
   without the effect, it cannot confirm anything; then the effect must just not make it worse
   (``-min_holdout_gain``). No held-out data (a few static points): the score alone decides
   and the report says so.

Physics outside the catalog: when the residual after the chosen effects stays far above the
noise, :func:`unexplained` words the warning every report prints, so a catalog effect is never
named as a confident identification there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.signal import savgol_filter

Array = NDArray[np.float64]

MIN_SAMPLES_FOR_RHO = 20
SMOOTH_WINDOW = 21


@dataclass(frozen=True, slots=True)
class Criterion:
    """Thresholds of the selection rule (the same for every model path)."""

    min_score: float = 10.0
    min_holdout_gain: float = 0.02


DEFAULT = Criterion()


@dataclass(frozen=True, slots=True)
class Verdict:
    """How one candidate effect fared against the rule."""

    score: float
    n_eff: float
    holdout_gain: float       # nan: no held-out data
    accepted: bool
    why: str


def _n_from_rho(r: Array, detrend: bool) -> float:
    r = np.asarray(r, float)
    r = r[np.isfinite(r)]
    n = len(r)
    if n < MIN_SAMPLES_FOR_RHO:
        return float(n)
    if detrend and n > 2 * SMOOTH_WINDOW:
        r = r - savgol_filter(r, SMOOTH_WINDOW, 3)
    r = r - np.mean(r)
    den = float(r @ r)
    rho = float(r[1:] @ r[:-1]) / den if den > 0 else 0.0
    rho = min(max(rho, 0.0), 0.999)
    return max(2.0, n * (1.0 - rho) / (1.0 + rho))


def effective_n(residual: Array) -> float:
    """Independent samples a residual is worth: the lag-1 autocorrelation of its fast part
    (the residual less a local cubic fit, i.e. the measurement noise as sampled) corrects for
    oversampled or coloured noise.  Slow structure left in the residual is not counted here:
    it is what the held-out check and the unexplained-residual warning are for."""
    return _n_from_rho(residual, detrend=True)


def structured_n(residual: Array) -> float:
    """Independent samples a residual is worth counting its slow structure too (the lag-1
    autocorrelation of the residual itself): what two candidates that both leave structure
    can be told apart by.  A white residual keeps ``n``; a slow one counts as few samples."""
    return _n_from_rho(residual, detrend=False)


def score(rss0: float, rss1: float, n: int, k_added: int, n_eff: float,
          noise: float | None = None) -> float:
    """Penalised likelihood gain of a model with ``k_added`` more parameters."""
    if n <= 0 or not math.isfinite(rss1):
        return -math.inf  # a model that cannot be simulated explains nothing
    if not math.isfinite(rss0) or rss1 <= 0:
        return math.inf
    if noise is not None and noise > 0:
        gain = (rss0 - rss1) / noise ** 2 * n_eff / n
    else:
        gain = n_eff * math.log(rss0 / rss1)
    return gain - k_added * math.log(max(n_eff, math.e))


def score_of(rss0: float, rss1: float, residual1: Array, k_added: int,
             noise: float | None = None, n_eff: float | None = None) -> tuple[float, float]:
    """(score, n_eff) of a candidate from its residual ``residual1`` (``n_eff`` given: the
    path knows its samples are independent, e.g. static equilibria)."""
    n = int(np.sum(np.isfinite(residual1)))
    ne = effective_n(residual1) if n_eff is None else n_eff
    return score(rss0, rss1, n, k_added, ne, noise), ne


def judge(rss0: float, rss1: float, residual1: Array, k_added: int = 1,
          holdout_gain: float = math.nan, holdout_informative: bool = True,
          noise: float | None = None, criterion: Criterion = DEFAULT,
          n_eff: float | None = None) -> Verdict:
    """Apply the rule to one candidate (``residual1``: the augmented model's residual)."""
    s, ne = score_of(rss0, rss1, residual1, k_added, noise, n_eff)
    if s < criterion.min_score:
        return Verdict(s, ne, holdout_gain, False,
                       f"score {s:.1f} < {criterion.min_score:g} (n_eff {ne:.0f})")
    if math.isnan(holdout_gain):
        return Verdict(s, ne, holdout_gain, True, f"score {s:.1f}; no held-out data")
    need = criterion.min_holdout_gain if holdout_informative else -criterion.min_holdout_gain
    if holdout_gain < need:
        return Verdict(s, ne, holdout_gain, False,
                       f"held-out gain {holdout_gain:.1%} < {need:.0%}")
    return Verdict(s, ne, holdout_gain, True,
                   f"score {s:.1f} (n_eff {ne:.0f}), held-out gain {holdout_gain:.1%}")


def unexplained(residual_rms: float, noise: float, factor: float = 3.0) -> str | None:
    """A warning when the residual left after the chosen effects stays far above the noise."""
    if noise <= 0 or not math.isfinite(residual_rms):
        return None
    ratio = residual_rms / noise
    if ratio < factor:
        return None
    return (f"unexplained residual: after the chosen effects the residual is {ratio:.0f}x the "
            f"noise; physics outside the catalog (or a transient) acts here, so treat the named "
            f"effects as the best catalog approximation, not as a confident identification")
