"""``teleop diagnose --model finger --finger N`` on ``teleop up --record`` hand recordings.

Recordings come from an independent generator (`tests/sim/hand_rec_gen.py`: the simulated
hand at 1 kHz with sensor noise and quantisation, finger parameters 3-5 % off nominal, irregular
40 Hz ticks); the diagnosis simulates the calibrated finger from the recorded set-points.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hand_rec_gen import flag_moving, hand_recording  # tests/sim/hand_rec_gen.py

from sim.finger_hand_rec import dynamixel_targets, hand_finger_data
from teleop.cli import main
from teleop.effects import EffectSet
from teleop.errors import RecordingError
from teleop.recording import Recording, read_recording, write_recording


def _diagnose(path: Path, tmp_path: Path, *extra: str) -> dict:  # type: ignore[type-arg]
    out = tmp_path / "d.json"
    assert main(["diagnose", str(path), "--model", "finger", "--finger", "1", "--json",
                 str(out), *extra]) == 0
    return json.loads(out.read_text())


@pytest.mark.slow
def test_a_command_delay_in_the_hand_is_found_from_the_recorded_set_points(tmp_path: Path) -> None:
    # a loop reading up to 30 ms late, with its read and write times recorded
    path = hand_recording(tmp_path / "hand.csv", 10.0, seed=5, effects=EffectSet(dead_time=0.06),
                          late_s=0.03, clock_columns=True)
    doc = _diagnose(path, tmp_path)
    assert doc["effects"], doc
    first = doc["effects"][0]
    assert first["name"] == "dead_time"
    assert set(first) >= {"name", "params", "delta_bic"} and first["delta_bic"] > 0
    assert abs(first["params"]["dead_time"] - 0.06) <= 0.01
    assert doc["fit"]["after"]["nrmse"] < 0.3 * doc["fit"]["before"]["nrmse"]


@pytest.mark.slow
def test_a_clean_hand_recording_reports_no_effect(tmp_path: Path) -> None:
    doc = _diagnose(hand_recording(tmp_path / "hand.csv", 10.0, seed=6, late_s=0.03,
                                   clock_columns=True), tmp_path)
    assert doc["effects"] == [], doc["effects"]
    assert doc["unexplained"] is None


def test_a_sensor_offset_is_named_across_restarts(tmp_path: Path) -> None:
    """A real offset on the angle sensors (0.2 rad), segments restarting mid-motion: named on
    the proximal angle (measured 0.198, score 369).  On the motor angle a position servo
    follows its own reading, so there an offset barely shows (and none is named); it used to
    be named at its 0.5 rad bound on the motor angle of recordings with restarts, with or
    without one (the restart's settle error, docs/diagnose-results.md).  Two flagged
    stretches: with a third the noise floor, estimated across the cut, rises to 0.013 rad
    and the selection stops there (open)."""
    path = tmp_path / "hand.csv"
    rec = read_recording(hand_recording(path, 4.0, seed=6, effects=EffectSet(sensor_offset=0.2),
                                        late_s=0.01, clock_columns=True, load_column=True))
    write_recording(path, flag_moving(rec, n=2))
    doc = _diagnose(path, tmp_path, "--output", "proximal_angle_rad")
    assert "restarts 3 time(s)" in doc["note"]  # two flagged, and the offset start
    assert [e["name"] for e in doc["effects"]] == ["sensor_offset"], doc["effects"]
    assert doc["effects"][0]["params"]["sensor_offset"] == pytest.approx(0.2, abs=0.03)


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


def test_the_dynamixel_drivers_overload_back_off_is_rebuilt_from_the_recorded_load() -> None:
    """Targets are the set-points, except while the filtered load (0.25 new + 0.75 old) is above
    the threshold: then the present angle - 0.05 rad (never above the set-point, never < 0)."""
    sp = np.array([1.0, 1.0, 1.0, 1.0, 1.0, 0.01])
    joint = np.array([0.2, 0.3, 0.4, 0.5, 0.6, 0.03])
    load = np.array([100.0, 1000.0, 1000.0, 0.0, 0.0, 1400.0])
    # filtered: 25, 268.75, 451.6, 338.7, 254.0, 540.5 against 350
    got = dynamixel_targets(sp, joint, load, 350.0, 0.25)
    assert np.allclose(got, [1.0, 1.0, 0.35, 1.0, 1.0, 0.0])


def test_a_gap_is_refused_in_one_line_or_restarts_the_simulation_with_split_gaps(
        tmp_path: Path) -> None:
    path = hand_recording(tmp_path / "hand.csv", 4.0, seed=3)
    rec = read_recording(path)
    t = rec.t_s.copy()
    t[80:] += 0.8  # a hand tick stalled 0.8 s after data row 80
    cut = Recording(rec.columns, np.column_stack([t, rec.data[:, 1:]]), rec.meta,
                    source=str(path))
    with pytest.raises(RecordingError, match=r"'t_s' has a gap .* data row 81"):
        hand_finger_data(cut, 1)
    data = hand_finger_data(cut, 1, split_gaps=True)
    assert data.active is not None and not data.active[79] and data.active[80]
    assert "gap" in data.note
    assert not np.any((data.t_s[data.keep] >= t[80]) & (data.t_s[data.keep] < t[80] + 0.15))
