"""A recording's columns for the axis diagnosis: checked signals, the initial state, the
output-error fit grid."""

from __future__ import annotations

import numpy as np

from teleop.diagnose.axis_model import Array
from teleop.diagnose.fit import Segment
from teleop.diagnose.results import DiagnoseOptions
from teleop.errors import RecordingError
from teleop.recording import Recording

MIN_SAMPLES = 200


def recording_signals(rec: Recording, opts: DiagnoseOptions) -> tuple[Array, Array | None, Array]:
    where = rec.source
    y = rec.column(opts.output_col)
    u = rec.column(opts.input_col) if opts.input_col else None
    t = rec.t_s
    for name, col in (("t_s", t), (opts.output_col, y)) + (
            ((opts.input_col, u),) if u is not None else ()):
        bad = ~np.isfinite(col)
        if np.any(bad):
            raise RecordingError(f"{where}: column {name!r} has a gap (missing or non-finite "
                                 f"value) at data row {int(np.argmax(bad)) + 1}")
    if len(t) < MIN_SAMPLES:
        raise RecordingError(f"{where}: column 't_s' has {len(t)} data rows, too short to "
                             f"diagnose (need at least {MIN_SAMPLES})")
    if float(np.std(y)) <= 0:
        raise RecordingError(f"{where}: column {opts.output_col!r} never changes; nothing to fit")
    dts = np.diff(t)
    if np.max(dts) > 5 * np.median(dts):
        i = int(np.argmax(dts))
        raise RecordingError(f"{where}: column 't_s' has a sampling gap of {dts[i]:.3g} s at "
                             f"data row {i + 2} (t={t[i + 1]:.6g} s; uneven sampling; split the "
                             "recording)")
    return t, u, y


def initial_state(t: Array, y: Array, span_s: float = 0.03) -> tuple[float, float]:
    """Position and velocity at the first sample from a quadratic fit over ``span_s``."""
    n = max(5, int(np.searchsorted(t, t[0] + span_s)))
    c = np.polyfit(t[:n] - t[0], y[:n], 2)
    return float(c[2]), float(c[1])


def decimate(t: Array, u: Array | None, y: Array, rate_hz: float) -> Segment:
    fs = 1.0 / float(np.median(np.diff(t)))
    m = max(1, int(round(fs / rate_hz)))
    if m == 1:
        return Segment(t, u, y)
    n = (len(t) // m) * m
    td, yd = t[:n:m], y[:n:m]
    ud = None if u is None else u[:n].reshape(-1, m).mean(axis=1)
    return Segment(td, ud, yd)
