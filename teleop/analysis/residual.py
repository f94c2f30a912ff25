"""Residual analysis: noise level, whiteness and what the residual correlates with."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from teleop.analysis.axis_model import Array


@dataclass(frozen=True, slots=True)
class ResidualStats:
    """Summary of a fit residual.

    ``noise_std`` is the measurement noise estimated from the data alone (second differences);
    ``whiteness`` is the fraction of autocorrelation lags 1..50 inside the 95 % band of white
    noise (near 0.95 for a white residual); ``corr`` holds correlation coefficients of the residual
    with named signals (input, position, velocity, sign of velocity).
    """

    rms: float
    noise_std: float
    lag1_autocorr: float
    whiteness: float
    corr: tuple[tuple[str, float], ...]

    @property
    def rms_over_noise(self) -> float:
        """How many times the noise level the residual is."""
        return self.rms / self.noise_std if self.noise_std > 0 else math.inf


def noise_std(y: Array) -> float:
    """Measurement noise of a smooth signal: robust std of its second difference / sqrt(6)."""
    d2 = np.diff(y, 2)
    if len(d2) == 0:
        return 0.0
    mad = float(np.median(np.abs(d2 - np.median(d2))))
    return 1.4826 * mad / math.sqrt(6.0)


def autocorr(r: Array, max_lag: int) -> Array:
    """Normalised autocorrelation at lags 0..max_lag."""
    r = r - np.mean(r)
    n = len(r)
    max_lag = min(max_lag, n - 1)
    f = np.fft.rfft(r, 2 * n)
    ac = np.fft.irfft(f * np.conj(f))[: max_lag + 1]
    return ac / ac[0] if ac[0] > 0 else np.zeros(max_lag + 1)


def _corr(a: Array, b: Array) -> float:
    sa, sb = float(np.std(a)), float(np.std(b))
    if sa == 0 or sb == 0:
        return 0.0
    return float(np.mean((a - a.mean()) * (b - b.mean())) / (sa * sb))


def analyse_residual(r: Array, y: Array, signals: dict[str, Array]) -> ResidualStats:
    """Statistics of residual ``r`` of measurement ``y``; ``signals`` are correlated against."""
    ac = autocorr(r, 50)
    band = 1.96 / math.sqrt(max(len(r), 1))
    white = float(np.mean(np.abs(ac[1:]) < band)) if len(ac) > 1 else 1.0
    corr = tuple((k, _corr(r, v)) for k, v in signals.items())
    return ResidualStats(float(np.sqrt(np.mean(r ** 2))), noise_std(y),
                         float(ac[1]) if len(ac) > 1 else 0.0, white, corr)
