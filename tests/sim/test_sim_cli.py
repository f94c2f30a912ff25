"""``teleop sim`` and ``teleop bench sim`` from the command line: outputs and bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from teleop.cli import main
from teleop.recording import read_recording


@pytest.mark.parametrize("argv", [
    ["sim", "nonsense"],
    ["sim", "weight", "--force-n", "nan"],
    ["sim", "weight", "--force-n", "-3"],
    ["sim", "weight", "--force-n", "heavy"],
    ["sim", "pull-unloaded", "--units", "inf"],
    ["sim", "position", "--effect", "warp_drive=1"],
    ["sim", "position", "--effect", "backlash"],
    ["sim", "position", "--effect", "backlash=-1"],
    ["sim", "position", "--duration", "0"],
])
def test_bad_input_is_one_line_exit_2(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "error" in err
    assert "Traceback" not in err


@pytest.mark.parametrize("flag", ["--out", "--json"])
def test_unwritable_output_fails_before_the_run(flag: str, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str],
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    import sim.experiments

    def never(*_a: object, **_k: object) -> None:
        raise AssertionError("the experiment ran although its output cannot be written")

    monkeypatch.setattr(sim.experiments, "run_experiment", never)
    assert main(["sim", "force-blocks", flag, str(tmp_path)]) == 2  # a directory
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is a directory" in err


def test_pull_unloaded_json(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", "pull-unloaded", "--units", "100", "--json", "-"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["motor_velocity_rad_s"] == pytest.approx(0.1781, rel=0.15)


def test_recording_csv_has_si_columns_and_is_deterministic(tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]
                                                           ) -> None:
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    for out in (a, b):
        assert main(["sim", "grasp", "--noise", "--seed", "7", "--duration", "2",
                     "--effect", "backlash=0.05", "--out", str(out)]) == 0
    rec = read_recording(a)
    for col in ("t_s", "motor_cmd_units", "tendon_force_n", "motor_angle_rad",
                "proximal_angle_rad", "distal_angle_rad", "motor_load_units",
                *(f"pressure_{i}" for i in range(9))):
        assert rec.has(col)
    assert rec.meta_value("experiment") == "grasp"
    assert "backlash" in (rec.meta_value("effects") or "")
    assert a.read_text() == b.read_text()
    c = tmp_path / "c.csv"
    assert main(["sim", "grasp", "--noise", "--seed", "8", "--duration", "2",
                 "--out", str(c)]) == 0
    assert not np.array_equal(read_recording(c).data, rec.data)


def test_force_blocks_recording(tmp_path: Path) -> None:
    out = tmp_path / "fb.csv"
    assert main(["sim", "force-blocks", "--out", str(out)]) == 0
    rec = read_recording(out)
    cmd = rec.column("motor_cmd_units")
    t = rec.t_s
    for t_mid, units in ((10.0, 30.0), (30.0, 60.0), (50.0, 90.0)):
        assert cmd[t.searchsorted(t_mid)] == units
    prox = rec.column("proximal_angle_rad")
    # 30 units (6 N) stays under the base spring's preload; 60 and 90 close the finger further
    assert prox[t.searchsorted(20.5)] < 0.01
    assert prox[t.searchsorted(40.5)] < prox[t.searchsorted(60.5)]
    assert prox[-1] < 0.05  # the position command returns it


def test_bench_sim_json(capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
                        ) -> None:
    import sim.bench

    real = sim.bench.bench_sim
    monkeypatch.setattr(sim.bench, "bench_sim", lambda: real(sim_time_s=1.0, repeats=1))
    assert main(["bench", "sim", "--json", "-"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["realtime_factor"] > 10.0
    assert data["hand_realtime_factor"] > 3.0
    assert all(isinstance(v, float) for v in data.values())


def test_repeated_effect_is_refused_in_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    from teleop.cli import main

    assert main(["sim", "weight", "--force-n", "9.8", "--effect", "gravity=1",
                 "--effect", "gravity=2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["teleop sim: error: --effect gravity given twice"]
