"""``teleop diagnose --model finger`` refines the motor's friction law (``speed_law_fraction``)
and ``--write-params`` writes it (issue 14)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from sim.experiments import ExperimentSpec, run_experiment
from sim.finger import ContactObject
from sim.finger_dynamic import PARAMS, FingerDynamicModel, dynamic_data
from sim.finger_model_file import load_model
from sim.params import default_finger_params
from teleop.cli import main
from teleop.effects import EffectSet
from teleop.recording import write_recording

TRUE_FRACTION = 0.7


def _recording(fraction: float, seed: int = 4):  # type: ignore[no-untyped-def]
    truth = replace(default_finger_params(), speed_law_fraction=fraction)
    spec = ExperimentSpec("position", duration_s=6.0, noise=True, seed=seed)
    return run_experiment(spec, truth, ContactObject(kind="none"), EffectSet()).recording


def test_the_nominal_fit_finds_the_friction_law_and_reaches_the_floor() -> None:
    model = FingerDynamicModel(default_finger_params(),
                               dynamic_data(_recording(TRUE_FRACTION), "motor_angle_rad"))
    fit = model.fit(model.nominal_start(), ())
    got = dict(zip(PARAMS, fit.theta, strict=True))["speed_law_fraction"]
    assert abs(got - TRUE_FRACTION) < 0.15
    floor, _ = model.floor()
    n = len(model.data.split()[0])
    assert np.sqrt(fit.rss / n) < 2.0 * floor  # where the effect search would not start


def test_write_params_writes_the_fraction_and_names_no_effect(tmp_path: Path) -> None:
    rec_path, m, j = tmp_path / "r.csv", tmp_path / "m.toml", tmp_path / "d.json"
    write_recording(rec_path, _recording(TRUE_FRACTION))
    assert main(["diagnose", str(rec_path), "--model", "finger", "--write-params", str(m),
                 "--json", str(j)]) == 0
    fp, eff = load_model(m)
    assert abs(fp.speed_law_fraction - TRUE_FRACTION) < 0.15
    assert eff == EffectSet()
    doc = json.loads(j.read_text())
    assert doc["effects"] == []
    assert doc["fit"]["after"]["params"]["speed_law_fraction"] == fp.speed_law_fraction
