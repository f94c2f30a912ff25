"""``teleop bench diagnose-finger``: clean JSON on stdout, figures that agree with each other."""

from __future__ import annotations

import json
import math

import pytest

from teleop.cli import main


def test_bench_diagnose_finger_json(capsys: pytest.CaptureFixture[str],
                                    monkeypatch: pytest.MonkeyPatch) -> None:
    import sim.finger_diagnose_bench as bench

    real = bench.bench_diagnose_finger
    monkeypatch.setattr(bench, "bench_diagnose_finger", lambda: real(duration_s=8.0))
    assert main(["bench", "diagnose-finger", "--json", "-"]) == 0
    out = capsys.readouterr()
    data = json.loads(out.out)  # the recording's summary went to stderr, not into the JSON
    assert "final_tendon_force_n" in out.err
    assert "diagnose: physics step" in out.err  # the diagnosis's progress, on stderr too
    assert data["rows"] == 8001 and data["recording_s"] == 8.0
    assert data["diagnose_s"] > 0.0 and data["diagnose_cpu_s"] > 0.0
    assert data["goal_s"] == 30.0
    assert data["goal_met"] == (data["diagnose_s"] <= 30.0)
    assert data["concealed_wave_per_rad"] == 100.0
    # the diagnosis explains the recording far better than the nominal finger does
    assert data["nrmse_after"] < 0.5 * data["nrmse_before"]
    # 8 s hold few periods, so where the term lands is the 60 s run's figure, not this test's;
    # the bench reports it either way
    assert math.isfinite(data["found_wave_per_rad"]) == (data["found_amplitude_n"] > 0.0)
