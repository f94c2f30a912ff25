"""Residual analysis: noise level, whiteness and what the residual correlates with."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_filter

from teleop.diagnose.axis_model import Array


@dataclass(frozen=True, slots=True)
class ResidualStats:
    """Summary of a fit residual.

    ``noise_std`` is the noise of the residual's own quantity (a position residual: the
    measurement noise from local cubic fits; an effort residual: that noise carried through
    the filter, the derivatives and the fitted model, :mod:`teleop.diagnose.ee_noise`);
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


def noise_std(y: Array, window: int = 21) -> float:
    """Measurement noise of a smooth signal: spread of its residual from a local cubic fit
    (Savitzky-Golay over ``window`` samples), corrected for the fit's leverage; robust (MAD)
    unless the signal is quantised so coarsely that the MAD is zero."""
    if len(y) < window + 2:
        return 0.0
    r = y - savgol_filter(y, window, 3)
    corr = 1.0 / math.sqrt(1.0 - 4.0 / window)
    mad = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    return (mad if mad > 0 else float(np.std(r))) * corr


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


def analyse_residual(r: Array, noise: float, signals: dict[str, Array]) -> ResidualStats:
    """Statistics of residual ``r`` whose noise level (in ``r``'s own units) is ``noise``;
    ``signals`` are correlated against."""
    ac = autocorr(r, 50)
    band = 1.96 / math.sqrt(max(len(r), 1))
    white = float(np.mean(np.abs(ac[1:]) < band)) if len(ac) > 1 else 1.0
    corr = tuple((k, _corr(r, v)) for k, v in signals.items())
    return ResidualStats(float(np.sqrt(np.mean(r ** 2))), noise,
                         float(ac[1]) if len(ac) > 1 else 0.0, white, corr)
