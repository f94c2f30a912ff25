"""``teleop diagnose --model finger --finger N`` on ``teleop up --record`` hand recordings.

Recordings come from an independent generator (`tests/sim/hand_rec_gen.py`: the simulated
hand at 1 kHz with sensor noise and quantisation, finger parameters 3-5 % off nominal, irregular
40 Hz ticks); the diagnosis simulates the calibrated finger from the recorded set-points.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hand_rec_gen import hand_recording  # tests/sim/hand_rec_gen.py

from teleop.cli import main
from teleop.effects import EffectSet


def _diagnose(path: Path, tmp_path: Path, *extra: str) -> dict:  # type: ignore[type-arg]
    out = tmp_path / "d.json"
    assert main(["diagnose", str(path), "--model", "finger", "--finger", "1", "--json",
                 str(out), *extra]) == 0
    return json.loads(out.read_text())


@pytest.mark.slow
def test_a_command_delay_in_the_hand_is_found_from_the_recorded_set_points(tmp_path: Path) -> None:
    path = hand_recording(tmp_path / "hand.csv", 10.0, seed=5, effects=EffectSet(dead_time=0.06))
    doc = _diagnose(path, tmp_path)
    assert doc["effects"], doc
    first = doc["effects"][0]
    assert first["name"] == "dead_time"
    assert abs(first["params"]["dead_time"] - 0.06) <= 0.01
    assert doc["fit"]["after"]["nrmse"] < 0.3 * doc["fit"]["before"]["nrmse"]


@pytest.mark.slow
def test_a_clean_hand_recording_reports_no_effect(tmp_path: Path) -> None:
    doc = _diagnose(hand_recording(tmp_path / "hand.csv", 10.0, seed=6), tmp_path)
    assert doc["effects"] == [], doc["effects"]
    assert doc["unexplained"] is None


@pytest.mark.slow
def test_contact_rows_are_excluded_with_a_note(tmp_path: Path) -> None:
    path = hand_recording(tmp_path / "hand.csv", 10.0, seed=7, obj="cylinder", max_rad=1.5)
    doc = _diagnose(path, tmp_path)
    assert doc["note"] and "contact" in doc["note"]
    assert doc["effects"] == [], doc["effects"]


@pytest.mark.parametrize("problem", ["finger", "gap", "nan", "no_finger_option", "column"])
def test_bad_hand_recordings_are_one_line_and_exit_2(problem: str, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    path = hand_recording(tmp_path / "hand.csv", 2.0, seed=1)
    lines = path.read_text().splitlines()
    head = [i for i, ln in enumerate(lines) if ln.startswith("t_s")][0]
    args = ["diagnose", str(path), "--model", "finger", "--finger", "1"]
    if problem == "finger":
        args[-1] = "4"
    elif problem == "gap":
        del lines[head + 20: head + 40]
    elif problem == "nan":
        cells = lines[head + 30].split(",")
        cells[lines[head].split(",").index("setpoint_rad_f1")] = "nan"
        lines[head + 30] = ",".join(cells)
    elif problem == "no_finger_option":
        args = args[:-2]
    elif problem == "column":
        cols = lines[head].split(",")
        cols[cols.index("setpoint_rad_f1")] = "other"
        lines[head] = ",".join(cols)
    path.write_text("\n".join(lines) + "\n")
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and str(path) in err and "Traceback" not in err, err
    assert {"finger": "--finger 4", "gap": "row", "nan": "row 30", "no_finger_option": "--finger",
            "column": "setpoint_rad_f1"}[problem] in err, err
