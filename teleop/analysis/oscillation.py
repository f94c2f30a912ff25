"""Sustained-oscillation detection of one signal against its own measured noise floor.

The one oscillation engine of the stability classifier (:mod:`teleop.analysis.stability`).

A signal is examined in *analysis segments*: stretches where the operator holds still and the
loop has had a round trip to close (one long hold after the grasp ramp in the sweep's
scenario, or every hold of a repeated grasp script).  Each segment is averaged in blocks down
to :attr:`OscillationCriteria.rate_hz` (the hand reports at 40 Hz and is held between its
ticks, so the raw 1 kHz series is a staircase), split into an early and a late half, and each
half detrended by a straight line: slow settling, drift and ramps are not oscillation.

Noise floor
    Measured from the run itself: the median of the periodogram of each detrended segment
    (Hann window: a narrow-band oscillation fills a few bins and leaves the median alone;
    the detrended segment's slow residue sits in the lowest bins), scaled to white
    noise over the band (median of an exponential variable = ln 2 x its mean), median over
    segments.  ``threshold = max(noise_multiple x noise, floor)``; ``floor`` is the signal's
    small absolute floor (a quantised signal at rest has zero measured noise).

Amplitude
    The RMS of the detrended half in excess of the noise, as the amplitude of the equivalent
    sine: ``sqrt(2 max(0, var - noise^2))``.  Frequency: the periodogram's peak (zero-padded).

Verdict
    *sustained*: late amplitude above the threshold, not decayed below
    :attr:`OscillationCriteria.decay_ratio` of the early amplitude, at least
    :attr:`OscillationCriteria.min_reversals` swings through +-0.9 threshold per segment
    and at least one in its late half (medians over the segments; a ramp, a step or an
    overshooting settle swings at most twice); *growing*: late amplitude above the threshold and
    :attr:`OscillationCriteria.growth_ratio` times the early one, with
    :attr:`OscillationCriteria.min_reversals_growing` swings.  Either needs the peak
    frequency to repeat :attr:`OscillationCriteria.min_cycles` times within a segment (a
    0.08 Hz "swing" in a 3 s hold is a settle in two steps, not an oscillation that can be
    seen there).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

__all__ = ["OscillationCriteria", "SignalOscillation", "analyse_oscillation", "noise_rms",
           "reversals", "segment_samples", "block_mean", "highpass"]


@dataclass(frozen=True, slots=True)
class OscillationCriteria:
    """Thresholds of the oscillation verdict (see the module doc)."""

    noise_multiple: float = 4.0
    decay_ratio: float = 0.5
    growth_ratio: float = 2.0
    min_reversals: int = 3
    min_reversals_growing: int = 6
    band_fraction: float = 0.9  # swings count through +-band_fraction x threshold
    rate_hz: float = 100.0
    min_segment_s: float = 0.6
    min_cycles: float = 1.5  # an oscillation must repeat within its segment to be one
    highpass_hz: float = 1.0  # fallback without analysis segments
    hf_hz: float = 5.0


@dataclass(frozen=True, slots=True)
class SignalOscillation:
    """The oscillation of one signal: amplitudes, frequency, noise, verdict."""

    name: str
    amplitude: float  # late halves, noise removed (equivalent sine amplitude, signal units)
    early_amplitude: float
    frequency_hz: float  # periodogram peak of the late halves (nan when flat)
    noise: float  # measured noise RMS at the analysis rate
    threshold: float  # max(noise_multiple x noise, floor)
    reversals: int  # swings through +-0.9 threshold per segment (median over segments)
    late_reversals: int  # the same in the late halves
    hf_power_fraction: float
    state: str  # "sustained", "growing" or "none"
    #: what was examined: "holds" (the analysis segments), "whole run" (no segments: the run
    #: high-passed) or "growth only" (a repeating script whose holds are all shorter than the
    #: round trip: the operator's own grasps fill the run, so only growth can be told)
    judged: str = "holds"

    @property
    def unstable(self) -> bool:
        """A sustained or growing oscillation."""
        return self.state != "none"

    @property
    def index(self) -> float:
        """Late amplitude over the threshold (> 1: above the noise-based threshold)."""
        return self.amplitude / self.threshold if self.threshold > 0 else math.inf

    def as_dict(self) -> dict[str, float | int | str | None]:
        """JSON form (nan as null)."""
        def num(v: float) -> float | None:
            return v if math.isfinite(v) else None

        return {"amplitude": num(self.amplitude), "early_amplitude": num(self.early_amplitude),
                "frequency_hz": num(self.frequency_hz), "noise": num(self.noise),
                "threshold": num(self.threshold), "reversals": self.reversals,
                "state": self.state, "judged": self.judged}


def block_mean(x: Array, n: int) -> Array:
    """Means of consecutive blocks of ``n`` samples (the incomplete tail dropped)."""
    m = len(x) // max(n, 1)
    return np.asarray(x[: m * n], float).reshape(m, n).mean(axis=1) if m else np.zeros(0)


def highpass(x: Array, dt_s: float, cutoff_hz: float) -> Array:
    """Zero-phase 2nd-order Butterworth high-pass of a uniformly sampled signal."""
    nyq = 0.5 / dt_s
    if cutoff_hz >= nyq or len(x) < 16:
        return x - np.mean(x)
    from scipy import signal as sps  # here: scipy.signal takes 1-3 s to import, and the
    # classifier needs it only without analysis segments (every spawned sweep worker imports this)

    sos = sps.butter(2, cutoff_hz / nyq, btype="highpass", output="sos")
    return np.asarray(sps.sosfiltfilt(sos, x, padtype="even"), dtype=float)


def _detrend(x: Array) -> Array:
    if len(x) < 3:
        return x - np.mean(x) if len(x) else x
    k = np.arange(len(x), dtype=float)
    return x - np.polyval(np.polyfit(k, x, 1), k)


def reversals(x: Array, band: float) -> int:
    """How many times ``x`` crosses from above ``+band`` to below ``-band`` or back."""
    above, below = x > band, x < -band
    marks = np.where(above, 1, np.where(below, -1, 0))
    marks = marks[marks != 0]
    return int(np.count_nonzero(np.diff(marks))) if marks.size > 1 else 0


def noise_rms(seg: Array) -> float:
    """White-noise RMS of a detrended segment from the median of its periodogram."""
    if len(seg) < 8:
        return 0.0
    w = np.hanning(len(seg))
    spec = np.abs(np.fft.rfft(seg * w)[2:]) ** 2  # Hann: leakage of a tone falls off fast
    # white noise of variance s^2: E|X_k|^2 = s^2 sum(w^2); median = ln 2 x mean
    return float(math.sqrt(np.median(spec) / math.log(2.0) / float(np.sum(w**2))))


def segment_samples(t_s: Array, x: Array, segments: Sequence[tuple[float, float]],
                    rate_hz: float, min_len_s: float) -> list[Array]:
    """``x`` within each segment, block-averaged to about ``rate_hz`` (short ones dropped)."""
    t = np.asarray(t_s, float)
    xs = np.asarray(x, float)
    out = []
    for a, b in segments:
        m = (t >= a) & (t < b)
        if np.count_nonzero(m) < 8 or b - a < min_len_s:
            continue
        tt = t[m]
        dt = float(np.median(np.diff(tt)))
        if not np.allclose(np.diff(tt), dt, rtol=1e-3, atol=1e-12):
            grid = np.arange(tt[0], tt[-1], dt)
            vals = np.interp(grid, tt, xs[m])
        else:
            vals = xs[m]
        block = max(1, int(round(1.0 / (rate_hz * dt))))
        out.append(block_mean(vals, block) if block > 1 else vals)
    return out


def _peak_hz(late: list[Array], dt_s: float, hf_hz: float) -> tuple[float, float]:
    """(frequency of the largest periodogram peak, share of power above hf) over halves."""
    best, best_f, total, hf_total = 0.0, math.nan, 0.0, 0.0
    for h in late:
        if len(h) < 8:
            continue
        n = 8 * len(h)
        spec = np.abs(np.fft.rfft(h * np.hanning(len(h)), n)) ** 2
        f = np.fft.rfftfreq(n, dt_s)
        spec[0] = 0.0
        total += float(spec.sum())
        hf_total += float(spec[f >= hf_hz].sum())
        k = int(np.argmax(spec))
        if spec[k] > best:
            best, best_f = float(spec[k]), float(f[k])
    return best_f, (hf_total / total if total > 0 else 0.0)


def _amplitude(halves: list[Array], noise: float) -> float:
    if not halves:
        return 0.0
    var = float(np.mean(np.concatenate([h**2 for h in halves])))
    return math.sqrt(2.0 * max(0.0, var - noise**2))


def analyse_oscillation(name: str, t_s: Array, x: Array,
                        segments: Sequence[tuple[float, float]], floor: float,
                        c: OscillationCriteria = OscillationCriteria(),
                        growth_only: bool = False) -> SignalOscillation:
    """The oscillation of ``x`` within ``segments`` (see the module doc).

    Without usable segments the whole run, high-passed at ``c.highpass_hz`` and without its
    first fifth, is the one segment; with ``growth_only`` (the run is the operator's own
    repeated motion, no hold to judge) only a *growing* oscillation is reported there: the
    grasps themselves would read as a sustained one.
    """
    t = np.asarray(t_s, float)
    xs = np.asarray(x, float)
    segs = segment_samples(t, xs, segments, c.rate_hz, c.min_segment_s)
    dt = 1.0 / c.rate_hz
    judged = "holds"
    if not segs:
        judged = "growth only" if growth_only else "whole run"
        whole = segment_samples(t, xs, [(t[0], t[-1] + 1e-9)], c.rate_hz, 0.0)
        if not whole or len(whole[0]) < 16:
            return SignalOscillation(name, 0.0, 0.0, math.nan, 0.0, floor, 0, 0, 0.0, "none",
                                     judged)
        dt = (t[-1] - t[0]) / max(len(whole[0]) - 1, 1)
        hp = highpass(whole[0], dt, c.highpass_hz)
        segs = [hp[len(hp) // 5:]]
    early, late, full = [], [], []
    for s in segs:
        half = len(s) // 2
        early.append(_detrend(s[:half]))
        late.append(_detrend(s[half:]))
        full.append(_detrend(s))
    noise = float(np.median([noise_rms(h) for h in late + early]))
    threshold = max(c.noise_multiple * noise, floor)
    amp_late = _amplitude(late, noise)
    amp_early = _amplitude(early, noise)
    band = c.band_fraction * threshold
    # per segment, median over segments: many holds each with a settling swing or two
    # are not an oscillation
    n_rev = int(np.median([reversals(h, band) for h in full]))
    n_late = int(np.median([reversals(h, band) for h in late]))
    freq, hf = _peak_hz(late, dt, c.hf_hz)
    # cycles of the peak frequency a segment holds: a swing slower than that (a settle in two
    # steps, a drift) cannot be told from a transient in this window
    cycles = freq * dt * float(np.median([len(s) for s in segs])) if math.isfinite(freq) else 0.0
    state = "none"
    if amp_late > threshold and n_late >= 1 and cycles >= c.min_cycles:
        if amp_late > c.growth_ratio * amp_early and n_rev >= c.min_reversals_growing:
            state = "growing"
        elif (amp_late >= c.decay_ratio * amp_early and n_rev >= c.min_reversals
              and judged != "growth only"):
            state = "sustained"
    return SignalOscillation(name, amp_late, amp_early, freq if amp_late > 0 else math.nan,
                             noise, threshold, n_rev, n_late, hf, state, judged)
