"""A recording's columns for the axis diagnosis: checked signals, the initial state, the
output-error fit grid."""

from __future__ import annotations

import numpy as np

from teleop.diagnose.axis_model import Array
from teleop.diagnose.fit import Segment
from teleop.diagnose.results import DiagnoseOptions
from teleop.errors import RecordingError
from teleop.recording import Recording
from teleop.recording_checks import finite_column, gap_rows

MIN_SAMPLES = 200


def recording_signals(rec: Recording, opts: DiagnoseOptions) -> tuple[Array, Array | None, Array]:
    """Time, input (None: a free response) and output, refused in one line
    (:mod:`teleop.recording_checks`) where a value is not a number, the recording is too
    short, the output never moves or the time column has a gap."""
    t = finite_column(rec, "t_s")
    y = finite_column(rec, opts.output_col)
    u = finite_column(rec, opts.input_col) if opts.input_col else None
    if len(t) < MIN_SAMPLES:
        raise RecordingError(f"{rec.source}: column 't_s' has {len(t)} data rows, too short "
                             f"to diagnose (need at least {MIN_SAMPLES})")
    if float(np.std(y)) <= 0:
        raise RecordingError(f"{rec.source}: column {opts.output_col!r} never changes; "
                             "nothing to fit")
    gap_rows(rec)  # refused: the axis path has no --split-gaps
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
