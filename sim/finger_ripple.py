"""The position-periodic shaft force as the finger diagnosis fits it (physics outside the catalog).

A cogging or detent force on the motor shaft, ``a sin(w th) + b cos(w th)`` N of tendon force
against the motor at shaft angle ``th`` (``FingerParams.shaft_ripple_*``, in both physics
engines), is carried through a fit as the library's sin/cos pair
(:mod:`teleop.diagnose.library`: ``term:sin:W`` and ``term:cos:W``, each with its amplitude);
the selection (:mod:`teleop.diagnose.select_sim_terms`) scans the wavenumber ``W`` on the grid
this module derives from the recording.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from teleop.diagnose.library import Term
from teleop.effects import EffectSet

Array = NDArray[np.float64]

#: fit bounds of either amplitude, N of tendon force (the motor's own friction is about 1 N)
AMPLITUDE_BOUNDS_N = (-20.0, 20.0)
#: the finest ripple scanned, 1/rad of shaft angle (period 0.05 rad): finer ones alias at the
#: fit's 50 Hz once the shaft turns faster than about 1 rad/s
WAVE_MAX_PER_RAD = 120.0
#: the coarsest: one and a half periods over the angle range the recording covers
MIN_PERIODS = 1.5


def split(effects: tuple[tuple[str, float], ...]) -> tuple[EffectSet, dict[str, float]]:
    """The catalog effects of a fit's (name, value) pairs, and the ``FingerParams`` fields of
    its shaft ripple (empty without one)."""
    eff = EffectSet()
    amp = {"sin": 0.0, "cos": 0.0}
    wave = 0.0
    for n, v in effects:
        if Term.is_key(n):
            t = Term.parse(n)
            if t.kind not in amp:
                raise ValueError(f"the finger has no library term {n!r}")
            amp[t.kind] = float(v)
            wave = t.const
        else:
            eff = eff.with_effect(n, v)
    if wave == 0.0:
        return eff, {}
    return eff, {"shaft_ripple_sin_n": amp["sin"], "shaft_ripple_cos_n": amp["cos"],
                 "shaft_ripple_per_rad": wave}


def wave_grid(span_rad: float) -> Array:
    """Wavenumbers to scan for a shaft that covered ``span_rad``: from :data:`MIN_PERIODS`
    periods over the span to :data:`WAVE_MAX_PER_RAD`, neighbours an eighth of a period apart
    at the span's end (empty when the shaft did not move)."""
    if not math.isfinite(span_rad) or span_rad <= 0.0:
        return np.zeros(0)
    lo = 2.0 * math.pi * MIN_PERIODS / span_rad
    return np.arange(lo, WAVE_MAX_PER_RAD, math.pi / (4.0 * span_rad))


#: fewer periods than this over the angle range covered: the term may be any smooth
#: position-dependent force (a spring the model has wrong), not a periodic one
PERIODS_TO_TELL = 3.0


def describe(fields: dict[str, float], span_rad: float = math.nan) -> str:
    """The ripple as one equation with units; with the shaft angle range the recording
    covers, how many periods that is (and, under :data:`PERIODS_TO_TELL`, that the data
    cannot tell it from a smooth position-dependent force)."""
    a, b, w = (fields["shaft_ripple_sin_n"], fields["shaft_ripple_cos_n"],
               fields["shaft_ripple_per_rad"])
    text = (f"shaft force against the motor [N of tendon force] = {a:.3g} sin({w:.4g} rad^-1 "
            f"* th) {'-' if b < 0 else '+'} {abs(b):.3g} cos({w:.4g} rad^-1 * th)   (th: motor "
            f"shaft angle, rad; amplitude {math.hypot(a, b):.3g} N, period "
            f"{2 * math.pi / w:.3g} rad): a position-periodic force outside the catalog "
            "(cogging, a detent, an eccentric load)")
    if math.isfinite(span_rad) and span_rad > 0:
        n = span_rad * w / (2 * math.pi)
        text += f"; the recording covers {n:.1f} periods of it"
        if n < PERIODS_TO_TELL:
            text += (f" (under {PERIODS_TO_TELL:g}: it may as well be any smooth "
                     "position-dependent force the model lacks, e.g. a spring it has wrong; "
                     "a recording over a wider angle range tells them apart)")
    return text
