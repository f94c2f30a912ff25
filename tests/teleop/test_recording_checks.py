"""One set of recording checks for every ``teleop diagnose`` model path: the axis model and the
finger's ``teleop sim`` recordings refuse the same fault in the same words, at one bound."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from sim.finger_dynamic import dynamic_data
from teleop.diagnose.axis_data import recording_signals
from teleop.diagnose.model import AxisNominal
from teleop.diagnose.results import DiagnoseOptions
from teleop.errors import RecordingError
from teleop.recording import Recording, read_recording
from teleop.recording_checks import MAX_GAP_FACTOR, gap_rows
from tests.sim.test_finger_diagnose import _corrupt


@pytest.mark.parametrize("factor", [0.9 * MAX_GAP_FACTOR, 1.1 * MAX_GAP_FACTOR])
def test_a_gap_is_a_step_over_the_bound_in_median_steps(factor: float) -> None:
    t = np.arange(300) * 1e-3
    t[150:] += (factor - 1.0) * 1e-3  # one step of ``factor`` median steps
    rec = replace(Recording.from_columns({"t_s": t, "angle_rad": np.sin(t)}), source="r.csv")
    if factor > MAX_GAP_FACTOR:
        with pytest.raises(RecordingError, match=r"'t_s' has a gap of .* at data row 151"):
            gap_rows(rec)
    else:
        assert gap_rows(rec).size == 0


def _words(call: object) -> str:
    """The one line a refused recording gets, without the file name."""
    with pytest.raises(RecordingError) as err:
        call()  # type: ignore[operator]
    return str(err.value).split(": ", 1)[1]


@pytest.mark.parametrize(("how", "says"), [
    ("nan-output", "column 'motor_angle_rad' is not finite at data row 91"),
    ("gap", "column 't_s' has a gap of 0.51 s at data row 121"),
])
def test_the_axis_and_finger_paths_refuse_a_fault_in_the_same_words(
        tmp_path: Path, how: str, says: str) -> None:
    rec = read_recording(_corrupt(tmp_path, "force-blocks", how), allow_nan=True)
    axis = DiagnoseOptions(AxisNominal(("viscous",), (None,)), None, "motor_angle_rad")
    words = _words(lambda: recording_signals(rec, axis))
    assert words.startswith(says), words
    assert words == _words(lambda: dynamic_data(rec, "motor_angle_rad"))
