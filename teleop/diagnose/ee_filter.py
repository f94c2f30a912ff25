"""The equation error's signals: the position low-passed by a zero-phase Butterworth filter and
differentiated twice, the friction law's velocity, several recordings laid end to end."""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import signal as sps

from teleop.diagnose.axis_model import Array

LAW_CUTOFF = 2.0
"""The friction sign law's velocity is filtered at this many times the cutoff: the law switches
where the velocity crosses zero, and a velocity smoothed as much as the regression's signals
moves the switch near a reversal (measured on a PD drive with Coulomb friction,
docs/diagnose-results.md: the low-speed equation error about 3x smaller)."""


@dataclass(frozen=True, slots=True)
class EESignals:
    """Filtered position, velocity, acceleration and input on the full time grid."""

    t: Array
    x: Array
    v: Array
    a: Array
    u: Array | None
    fs_hz: float
    cutoff_hz: float
    step: int          # decimation of the regression rows (roughly independent residuals)
    v_law: Array | None = None   # velocity for the friction sign law (a wider filter), else v

    @property
    def sign(self) -> Array:
        """The friction sign law ``tanh(v / eps)``, ``eps`` 2 % of the velocity's spread, on
        :attr:`v_law`."""
        v = self.v if self.v_law is None else self.v_law
        return np.tanh(v / (0.02 * float(np.std(self.v)) + 1e-12))


@functools.lru_cache(maxsize=64)
def _sos(wn: float) -> Array:
    """The filter's second-order sections (designing them costs more than filtering)."""
    return sps.butter(2, wn, output="sos")


def _filt(sig: Array, fs: float, fc: float) -> Array:
    """Zero-phase low-pass (a 2-D array: every column, one by one).  Filtering the columns in
    one call (``axis=0``) is faster but not bit-identical here, and measured, one independent
    cogging case (seed 106) then named ``nonlinear_stiffness`` beside its periodic term instead
    of a delayed-input term: sin + k3 and sin + u(t - 0.1 s) fit to the same NRMSE (0.00229),
    so last-bit differences pick between them."""
    sos = _sos(min(fc / (fs / 2), 0.9))
    if sig.ndim == 1:
        return sps.sosfiltfilt(sos, sig)
    return np.column_stack([sps.sosfiltfilt(sos, c) for c in sig.T])


def ee_signals(t: Array, y: Array, u: Array | None, cutoff_hz: float | None = None) -> EESignals:
    """Filter and differentiate ``y``; the cutoff defaults to fs/20, at most 15 Hz."""
    fs = 1.0 / float(np.median(np.diff(t)))
    fc = cutoff_hz or min(15.0, fs / 20)
    x = _filt(y, fs, fc)
    v = np.gradient(x, t)
    a = np.gradient(v, t)
    uf = None if u is None else np.asarray(u, float)
    step = max(1, int(fs / (4 * fc)))
    v_law = np.gradient(_filt(y, fs, min(LAW_CUTOFF * fc, 0.45 * fs)), t)
    return EESignals(t, x, v, a, uf, fs, fc, step, v_law)


def contiguous(ts: Sequence[Array]) -> Array:
    """Segment time bases laid end to end (the first keeps its own times)."""
    if len(ts) == 1:
        return ts[0]
    out, off = [], float(ts[0][0])
    for t in ts:
        out.append(t - t[0] + off)
        off = float(out[-1][-1] + (t[1] - t[0]))
    return np.concatenate(out)


def concat_ee(sigs: Sequence[EESignals]) -> EESignals:
    """Several recordings' filtered signals laid end to end."""
    if len(sigs) == 1:
        return sigs[0]
    u = None if sigs[0].u is None else np.concatenate([s.u for s in sigs])  # type: ignore[misc]
    return EESignals(contiguous([s.t for s in sigs]), np.concatenate([s.x for s in sigs]),
                     np.concatenate([s.v for s in sigs]), np.concatenate([s.a for s in sigs]),
                     u, sigs[0].fs_hz, sigs[0].cutoff_hz, sigs[0].step,
                     None if any(s.v_law is None for s in sigs)
                     else np.concatenate([s.v_law for s in sigs]))  # type: ignore[misc]
