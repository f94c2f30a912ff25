"""Stability and passivity metrics of one teleoperation run (pure functions over time series).

A run is given as :class:`RunSignals` (uniformly or non-uniformly sampled numpy arrays on one
time base); :func:`classify_run` turns it into :class:`RunMetrics`.

Definitions
-----------
``stable``
    The loop shows **no sustained and no growing oscillation**, and every signal stays finite.
    The oscillation signals are the hand set-point, the finger angle and the displayed force.
    First the operator-driven part is removed.  When the run says when the operator holds
    still and the loop has closed (:attr:`RunSignals.settle_s`: end of the grasp ramp plus a
    round trip; the sweep's scenario is one close and a long hold), the part after it is
    split into an early and a late half, each detrended by a straight line (slow settling is
    not oscillation).  Otherwise the run is high-passed at
    :attr:`StabilityCriteria.highpass_hz` and windowed by fractions.  The RMS of what remains,
    over the signal's scale (the set-point range for angles, the trigger's force limit for the
    force), is compared:

    * sustained: late RMS above :attr:`StabilityCriteria.sustained_fraction` of the scale, not
      decayed below :attr:`StabilityCriteria.decay_ratio` of the early RMS, with at least
      :attr:`StabilityCriteria.min_reversals_sustained` swings through a band of
      :attr:`StabilityCriteria.reversal_band_fraction` of the scale (a limit cycle: saturation
      keeps a delayed unstable loop bounded, so growth alone would miss it; with long delays
      it is slow, a relay-like swing between the force limits every few seconds);
    * growing: late RMS more than :attr:`StabilityCriteria.growth_ratio` times the early one,
      above :attr:`StabilityCriteria.floor_fraction` of the scale, with at least
      :attr:`StabilityCriteria.min_reversals_growing` swings (an oscillation, not a slow
      transient out of a saturated start).

    The share of oscillation power above :attr:`StabilityCriteria.hf_hz` (~5 Hz) is reported
    as ``hf_power_fraction`` (Rodriguez-Seda et al. 2009) but does not decide ``stable``: the
    delay-induced oscillations of this loop are slow (0.2-2 Hz; the finger servo is a 0.3 s
    lag).

``passive``
    The controller plus the channel generate no energy: the energy delivered out of the two
    ports (into the operator's finger and into the hand's environment) never exceeds the
    energy taken in at the ports plus the initial energy of the tanks, at every sample, within
    a numerical tolerance (:attr:`StabilityCriteria.energy_tol_j` plus
    :attr:`StabilityCriteria.energy_rel_tol` of the energy throughput).
    ``energy_generated_j`` is the largest excess over the run (<= 0 when passive).

``tracking_rms_rad``
    RMS of the finger angle against the set-point delayed by the forward path delay (what the
    hand could at best do).

``force_rms_n``
    RMS of the displayed force against the force measured at the hand, delayed by the backward
    path delay.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import signal as sps

Array = NDArray[np.float64]

__all__ = [
    "RunSignals", "StabilityCriteria", "OscillationMetrics", "RunMetrics",
    "classify_run", "oscillation_metrics", "energy_generated_j", "delayed", "rms_error",
    "highpass",
]


@dataclass(frozen=True, slots=True)
class RunSignals:
    """The time series of one run that the metrics need (all arrays share ``t_s``).

    ``energy_out_j``/``energy_in_j`` are cumulative energies (monotone, >= 0) delivered out of
    and taken in at the two physical ports together (operator's finger, hand environment).
    ``tank_j`` has one column per tank (may have zero columns for controllers without tanks).
    """

    t_s: Array
    setpoint_rad: Array
    finger_rad: Array
    force_displayed_n: Array
    force_measured_n: Array
    energy_out_j: Array
    energy_in_j: Array
    tank_j: Array
    initial_energy_j: float = 0.0
    forward_delay_s: float = 0.0
    backward_delay_s: float = 0.0
    setpoint_scale_rad: float = 3.0
    force_scale_n: float = 8.0
    limited_count: int = 0
    steps: int = 0
    dropped_messages: int = 0
    settle_s: float = 0.0  # from here on the operator holds still and the loop has closed


@dataclass(frozen=True, slots=True)
class StabilityCriteria:
    """Thresholds of the ``stable`` and ``passive`` classification (see the module doc)."""

    highpass_hz: float = 2.0
    hf_hz: float = 5.0
    early_window: tuple[float, float] = (0.2, 0.5)
    late_window: tuple[float, float] = (0.6, 1.0)
    sustained_fraction: float = 0.08
    decay_ratio: float = 0.5
    growth_ratio: float = 2.0
    floor_fraction: float = 0.01
    energy_tol_j: float = 1e-6
    energy_rel_tol: float = 1e-6
    min_observe_s: float = 1.0
    min_reversals_sustained: int = 2
    min_reversals_growing: int = 6
    reversal_band_fraction: float = 0.01


@dataclass(frozen=True, slots=True)
class OscillationMetrics:
    """Oscillation of one signal after removing its operator-driven component."""

    early_rms: float
    late_rms: float
    scale: float
    hf_power_fraction: float
    reversals: int = 1_000_000  # swings through +-band (after settling, or in the late window)

    @property
    def late_fraction(self) -> float:
        """Late RMS as a fraction of the signal's scale."""
        return self.late_rms / self.scale if self.scale > 0 else math.inf

    @property
    def growth(self) -> float:
        """Late RMS over early RMS (inf when the early window is quiet and the late is not)."""
        if self.early_rms > 0:
            return self.late_rms / self.early_rms
        return 1.0 if self.late_rms == 0 else math.inf

    def sustained(self, c: StabilityCriteria) -> bool:
        """Late oscillation above the sustained-amplitude threshold and not dying away."""
        return (self.late_fraction > c.sustained_fraction and self.growth > c.decay_ratio
                and self.reversals >= c.min_reversals_sustained)

    def growing(self, c: StabilityCriteria) -> bool:
        """Late oscillation grown by ``growth_ratio`` and above the noise floor."""
        return (self.late_fraction > c.floor_fraction and self.growth > c.growth_ratio
                and self.reversals >= c.min_reversals_growing)


@dataclass(frozen=True, slots=True)
class RunMetrics:
    """What :func:`classify_run` reports for one run."""

    stable: bool
    passive: bool
    energy_generated_j: float
    tracking_rms_rad: float
    force_rms_n: float
    tank_min_j: float
    limited_count: int
    limited_fraction: float
    dropped_messages: int
    oscillation_index: float  # largest late oscillation RMS / scale over the signals
    growth_ratio: float  # largest late/early oscillation ratio over the signals
    hf_power_fraction: float  # largest share of oscillation power above hf_hz
    reason: str  # why unstable ("" when stable)


def _uniform(t: Array, x: Array) -> tuple[Array, float]:
    """``x`` resampled on a uniform grid with the median step of ``t``."""
    dt = float(np.median(np.diff(t)))
    if np.allclose(np.diff(t), dt, rtol=1e-6, atol=1e-12):
        return x, dt
    grid = np.arange(t[0], t[-1] + 0.5 * dt, dt)
    return np.interp(grid, t, x), dt


def highpass(x: Array, dt_s: float, cutoff_hz: float) -> Array:
    """Zero-phase 2nd-order Butterworth high-pass of a uniformly sampled signal."""
    nyq = 0.5 / dt_s
    if cutoff_hz >= nyq or len(x) < 16:
        return x - np.mean(x)
    sos = sps.butter(2, cutoff_hz / nyq, btype="highpass", output="sos")
    return np.asarray(sps.sosfiltfilt(sos, x, padtype="even"), dtype=float)


def _window(n: int, frac: tuple[float, float]) -> slice:
    a, b = int(round(frac[0] * n)), int(round(frac[1] * n))
    return slice(min(a, n - 1), max(b, min(a, n - 1) + 1))


def reversals(x: Array, band: float) -> int:
    """How many times ``x`` crosses from above ``+band`` to below ``-band`` or back."""
    state, count = 0, 0
    for v in np.asarray(x, float):
        if v > band and state <= 0:
            count += state < 0
            state = 1
        elif v < -band and state >= 0:
            count += state > 0
            state = -1
    return int(count)


def _detrend(x: Array) -> Array:
    if len(x) < 2:
        return x - np.mean(x) if len(x) else x
    k = np.arange(len(x), dtype=float)
    return x - np.polyval(np.polyfit(k, x, 1), k)


def oscillation_metrics(t_s: Array, x: Array, scale: float,
                        c: StabilityCriteria = StabilityCriteria(),
                        settle_s: float = 0.0) -> OscillationMetrics:
    """Early/late oscillation RMS and high-frequency share of ``x`` (see module doc).

    With ``settle_s > 0`` (the operator holds still from then on) the part after ``settle_s``
    is split into an early and a late half, each detrended by a straight line (slow settling
    is not oscillation); otherwise the run is high-passed and windowed by fractions.
    """
    t = np.asarray(t_s, float)
    if settle_s > 0 and t[-1] - settle_s >= c.min_observe_s:
        xu, dt = _uniform(t, np.asarray(x, float))
        tu = t[0] + dt * np.arange(len(xu))
        seg = xu[tu >= settle_s]
        half = len(seg) // 2
        early, late = _detrend(seg[:half]), _detrend(seg[half:])
        hp = _detrend(seg)
        swinging = hp
    else:
        xu, dt = _uniform(t, np.asarray(x, float))
        hp = highpass(xu, dt, c.highpass_hz)
        n = len(hp)
        early, late = hp[_window(n, c.early_window)], hp[_window(n, c.late_window)]
        swinging = late
    n = len(hp)
    early_rms = float(np.sqrt(np.mean(early**2)))
    late_rms = float(np.sqrt(np.mean(late**2)))
    spec = np.abs(np.fft.rfft(hp)) ** 2
    freqs = np.fft.rfftfreq(n, dt)
    total = float(np.sum(spec))
    hf = float(np.sum(spec[freqs >= c.hf_hz]) / total) if total > 0 else 0.0
    return OscillationMetrics(early_rms, late_rms, scale, hf,
                              reversals(swinging, c.reversal_band_fraction * scale))


def delayed(t_s: Array, x: Array, delay_s: float) -> Array:
    """``x(t - delay_s)`` on the grid ``t_s`` (held at its first value before the start)."""
    return np.interp(np.asarray(t_s) - delay_s, t_s, x, left=float(x[0]))


def rms_error(t_s: Array, actual: Array, reference: Array, delay_s: float) -> float:
    """RMS of ``actual(t) - reference(t - delay_s)``."""
    err = np.asarray(actual) - delayed(t_s, np.asarray(reference), delay_s)
    return float(np.sqrt(np.mean(err**2))) if len(err) else 0.0


def energy_generated_j(energy_out_j: Array, energy_in_j: Array, initial_energy_j: float) -> float:
    """Largest excess of energy delivered over energy taken plus initial tank energy."""
    excess = np.asarray(energy_out_j) - np.asarray(energy_in_j) - initial_energy_j
    return float(np.max(excess)) if len(excess) else 0.0


def classify_run(s: RunSignals, c: StabilityCriteria = StabilityCriteria()) -> RunMetrics:
    """Classify one run as stable/passive and compute its error and energy metrics."""
    t = np.asarray(s.t_s, float)
    osc_signals = {
        "set-point": (s.setpoint_rad, s.setpoint_scale_rad),
        "finger angle": (s.finger_rad, s.setpoint_scale_rad),
        "displayed force": (s.force_displayed_n, s.force_scale_n),
    }
    reasons: list[str] = []
    finite = all(np.all(np.isfinite(a)) for a in
                 (t, s.setpoint_rad, s.finger_rad, s.force_displayed_n, s.force_measured_n))
    osc_index, growth, hf = 0.0, 0.0, 0.0
    if not finite:
        reasons.append("non-finite signal")
    else:
        for name, (x, scale) in osc_signals.items():
            m = oscillation_metrics(t, np.asarray(x, float), scale, c, s.settle_s)
            osc_index = max(osc_index, m.late_fraction)
            growth = max(growth, m.growth if math.isfinite(m.growth) else 1e9)
            hf = max(hf, m.hf_power_fraction)
            if m.sustained(c):
                reasons.append(f"sustained {name} oscillation ({m.late_fraction:.1%} of scale)")
            elif m.growing(c):
                reasons.append(f"growing {name} oscillation (x{m.growth:.1f})")
    gen = energy_generated_j(s.energy_out_j, s.energy_in_j, s.initial_energy_j)
    throughput = float(np.max(s.energy_out_j, initial=0.0) + np.max(s.energy_in_j, initial=0.0))
    tol = c.energy_tol_j + c.energy_rel_tol * (throughput + s.initial_energy_j)
    tank = np.asarray(s.tank_j, float)
    tank_min = float(np.min(tank)) if tank.size else math.nan
    return RunMetrics(
        stable=not reasons,
        passive=bool(np.isfinite(gen) and gen <= tol),
        energy_generated_j=gen,
        tracking_rms_rad=rms_error(t, s.finger_rad, s.setpoint_rad, s.forward_delay_s),
        force_rms_n=rms_error(t, s.force_displayed_n, s.force_measured_n, s.backward_delay_s),
        tank_min_j=tank_min,
        limited_count=int(s.limited_count),
        limited_fraction=(s.limited_count / s.steps) if s.steps else 0.0,
        dropped_messages=int(s.dropped_messages),
        oscillation_index=osc_index,
        growth_ratio=growth,
        hf_power_fraction=hf,
        reason="; ".join(reasons),
    )
