"""The finger as a ``teleop diagnose`` nominal model (static weight test)."""

from __future__ import annotations

import numpy as np

from sim.finger import weight_equilibrium
from sim.finger_diagnose import FingerStaticModel
from sim.params import default_finger_params
from teleop.effects import EffectSet


def test_static_model_is_the_weight_equilibrium_plus_the_sensor_offset() -> None:
    p = default_finger_params()
    model = FingerStaticModel(p, 0.2)
    forces = np.array([9.8, 15.7])
    t = np.arange(2.0)
    y = model.simulate(model.initial(), EffectSet(), t, forces)
    assert np.allclose(y, [weight_equilibrium(p, f)[0] for f in forces])
    y2 = model.simulate(model.initial(), EffectSet(sensor_offset=0.05), t, forces)
    assert np.allclose(y2 - y, 0.05)
    lo, hi = model.bounds()
    assert np.all(lo < model.initial()) and np.all(model.initial() < hi)
    assert set(model.candidates()) <= {"sensor_offset", "nonlinear_stiffness", "gravity"}


def _sim_rec(tmp_path, name: str, duration_s: float, effects: EffectSet):  # type: ignore[no-untyped-def]
    from sim.experiments import ExperimentSpec, run_experiment
    from sim.finger import ContactObject
    from teleop.recording import write_recording

    rec = run_experiment(ExperimentSpec(name, duration_s=duration_s), default_finger_params(),
                         ContactObject(kind="none"), effects).recording
    path = tmp_path / f"{name}.csv"
    write_recording(path, rec)
    return path


def test_unsupported_finger_recording_fails_fast_in_one_line(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    import time

    from teleop.cli import main

    path = _sim_rec(tmp_path, "weight", 0.5, EffectSet())
    t0 = time.perf_counter()
    assert main(["diagnose", str(path), "--model", "finger"]) == 2
    assert time.perf_counter() - t0 < 5.0
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--model axis" in err and "Traceback" not in err


def test_dynamic_force_step_on_the_command_line_finds_the_concealed_backlash(tmp_path) -> None:  # type: ignore[no-untyped-def]
    import json

    from teleop.cli import main

    path = _sim_rec(tmp_path, "force-step", 3.0, EffectSet(backlash=0.03))
    out = tmp_path / "d.json"
    assert main(["diagnose", str(path), "--model", "finger", "--tolerance", "0.05",
                 "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc["effects"][0]["name"] == "backlash"
    assert abs(doc["effects"][0]["params"]["backlash"] - 0.03) < 0.005
    # the JSON contract every diagnose path keeps (DESIGN.md): name, params, delta_bic
    assert set(doc["effects"][0]) >= {"name", "params", "delta_bic"}
    assert doc["effects"][0]["delta_bic"] > 0
    assert doc["fit"]["after"]["nrmse"] < 0.1 * doc["fit"]["before"]["nrmse"]
