"""What ``teleop diagnose`` refuses in a recording, in one line naming the file, column and row.

One set of checks for every model path: the axis model
(:func:`teleop.diagnose.axis_data.recording_signals`), the ``teleop sim`` finger recordings
(:func:`sim.finger_dynamic.dynamic_data`) and the ``teleop up --record`` hand recordings
(:mod:`sim.finger_hand_rec`): a command or output that is not a number where it is used, a
gap in the time column, too few samples to compare.
"""

from __future__ import annotations

import numpy as np

from teleop.errors import RecordingError
from teleop.recording import Recording

MAX_GAP_FACTOR = 10.0      # a step this many median steps long is a gap
MIN_COMPARED = 40          # fewer compared samples than this: too short to diagnose


def finite_column(rec: Recording, name: str, used: np.ndarray | None = None) -> np.ndarray:
    """Column ``name``, refused at its first row that is not finite among the ``used`` ones
    (a boolean mask; None: every row)."""
    v = rec.column(name)
    bad = ~np.isfinite(v)
    if used is not None:
        bad &= used
    if bad.any():
        raise RecordingError(f"{rec.source}: column {name!r} is not finite at data row "
                             f"{int(np.argmax(bad)) + 1}")
    return v


def gap_rows(rec: Recording, split: bool = False, can_split: bool = False) -> np.ndarray:
    """Rows after which the time column has a gap (a step over :data:`MAX_GAP_FACTOR` median
    steps: a stalled tick, a cut-out stretch): refused in one line unless ``split`` (the
    message offers ``--split-gaps`` where the caller ``can_split``)."""
    t = rec.t_s
    if len(t) < 3:
        raise RecordingError(f"{rec.source}: {len(t)} rows is too short to diagnose")
    dts = np.diff(t)
    med = float(np.median(dts))
    gap = dts > MAX_GAP_FACTOR * med
    if gap.any() and not split:
        i = int(np.argmax(gap))
        raise RecordingError(f"{rec.source}: column 't_s' has a gap of {dts[i]:.3g} s at data "
                             f"row {i + 2} (median step {med:.3g} s); split the recording"
                             f"{',' if can_split else ' or'} --skip {t[i + 1] - t[0]:.3g} past "
                             f"it{', or --split-gaps' if can_split else ''}")
    return np.flatnonzero(gap)


def enough_compared(rec: Recording, n: int, what: str) -> None:
    """Refuse fewer than :data:`MIN_COMPARED` compared samples (``what`` says which)."""
    if n < MIN_COMPARED:
        raise RecordingError(f"{rec.source}: {n} {what} is too few to diagnose (need "
                             f"{MIN_COMPARED})")
