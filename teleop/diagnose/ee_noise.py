"""The noise floor of the equation-error (effort) residual.

The equation error is an effort: ``sum(coef col(x, v, a, u)) - target`` on filtered signals.
Its noise is not the position noise: the measured position's noise passes through the filter,
two derivatives and the fitted model (inertia x acceleration, viscous x velocity, the friction
law's sign near reversals...).  The floor is measured by doing exactly that: the position is
measured once more with fresh noise of the level estimated from the recording (local cubic
fits, :func:`teleop.diagnose.residual.noise_std`), the fitted model is applied to both, and the
spread of the difference is what the residual would be from measurement noise alone.  The
commanded effort is taken as exact (it is what the controller applied).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from teleop.diagnose.axis_model import Array
from teleop.diagnose.ee_filter import EESignals, concat_ee, ee_signals
from teleop.diagnose.equation_error import EEFit, ee_apply
from teleop.diagnose.model import AxisNominal
from teleop.diagnose.residual import noise_std
from teleop.diagnose.windows import Window, locate_windows, moving_rms

Raw = tuple[Array, Array | None, Array]   # (t_s, input or None, measured position)


def ee_noise(raw: Sequence[Raw], sig: EESignals, nominal: AxisNominal, fit: EEFit,
             fixed_inertia: float, valid: Array, draws: int = 2, seed: int = 0) -> Array:
    """Per-sample noise floor (effort units) of ``fit``'s equation error on ``sig`` (the
    recordings ``raw`` filtered and laid end to end): the rms over ``draws`` fresh
    position-noise draws of the change in the residual, averaged over a few filter periods.
    ``valid`` marks samples outside the filter's edge transients."""
    rng = np.random.default_rng(seed)
    base = ee_apply(sig, nominal, fit, fixed_inertia)
    sq = np.zeros(len(sig.t))
    for _ in range(draws):
        noisy = [ee_signals(t, y + noise_std(y) * rng.standard_normal(len(y)), u,
                            sig.cutoff_hz) for t, u, y in raw]
        d = ee_apply(concat_ee(noisy), nominal, fit, fixed_inertia) - base
        sq += np.where(np.isfinite(d), d, 0.0) ** 2
    sq /= draws
    width = max(1, int(4 * sig.fs_hz / sig.cutoff_hz))
    local = np.convolve(sq, np.ones(width) / width, mode="same")
    overall = float(np.mean(sq[valid])) if np.any(valid) else 0.0
    return np.sqrt(np.maximum(local, 0.01 * overall))   # never below a tenth of the level


def noise_level(floor: Array, valid: Array) -> float:
    """The recording-wide noise level: rms of the per-sample floor over valid samples."""
    return float(np.sqrt(np.mean(floor[valid] ** 2))) if np.any(valid) else 0.0


def excess_windows(t: Array, x: Array, r: Array, floor: Array, valid: Array,
                   conds: dict[str, Array], span_s: float = 0.2) -> tuple[Window, ...]:
    """Where the residual ``r`` stays above its noise ``floor`` (moving rms over ``span_s``
    against the floor; windows over 3x, labelled by operating condition, each with the
    position range it covers in ``why``)."""
    dt = float(np.median(np.diff(t)))
    score = np.where(valid & (floor > 0), moving_rms(r, int(span_s / dt))
                     / np.where(floor > 0, floor, 1.0), 0.0)
    out = []
    for w in locate_windows(t, score, conds):
        m = (t >= w.t_start_s) & (t <= w.t_end_s)
        out.append(Window(w.t_start_s, w.t_end_s, f"{w.why}; position {float(np.min(x[m])):.4g}"
                          f" to {float(np.max(x[m])):.4g}", w.excess))
    return tuple(out)
