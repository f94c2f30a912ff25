"""The finger as a ``teleop diagnose`` nominal model (static weight test)."""

from __future__ import annotations

import numpy as np
import pytest

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


def test_the_physics_step_reported_is_the_one_the_rows_are_stepped_at() -> None:
    """At least one physics step per recorded row: rows finer than the 2 ms step (``teleop
    sim`` at 1 kHz) are stepped at their own span, and the report says so (it said 2 ms on
    such recordings, whose physics ran at 1 ms)."""
    from sim.finger import MotorCommand
    from sim.finger_dynamic import DynamicData, FingerDynamicModel

    def model(span_s: float) -> FingerDynamicModel:
        t = np.arange(50) * span_s
        data = DynamicData(t, tuple(MotorCommand("force", force_units=40.0) for _ in t),
                           np.zeros(len(t)), "motor_angle_rad", np.arange(len(t)), 1e-3)
        return FingerDynamicModel(default_finger_params(), data)

    assert model(1e-3).dt_s == 2e-3
    assert abs(model(1e-3).physics_step_s() - 1e-3) < 1e-12
    assert abs(model(0.5e-3).physics_step_s() - 0.5e-3) < 1e-12
    assert abs(model(10e-3).physics_step_s() - 2e-3) < 1e-12
    assert abs(model(3e-3).physics_step_s() - 1.5e-3) < 1e-12  # 1.5 steps: two of 1.5 ms


def _corrupt(tmp_path, name: str, how: str):  # type: ignore[no-untyped-def]
    """A 2 s ``teleop sim`` recording (100 Hz) broken one way."""
    from dataclasses import replace

    from teleop.recording import read_recording, write_recording

    rec = read_recording(_sim_rec(tmp_path, name, 2.0, EffectSet()))
    data = rec.data.copy()
    col = {c: i for i, c in enumerate(rec.columns)}
    if how == "nan-command":
        data[70, col["motor_cmd_units" if name != "position" else "setpoint_rad"]] = np.nan
    elif how == "nan-output":
        data[90, col["motor_angle_rad"]] = np.nan
    elif how == "gap":
        data[120:, col["t_s"]] += 0.5
    elif how == "short":
        data = data[:60]
    path = tmp_path / f"{how}.csv"
    write_recording(path, replace(rec, data=data))
    return path


@pytest.mark.parametrize(("name", "how", "says"), [
    ("force-blocks", "nan-command", "column 'motor_cmd_units' is not finite at data row 71"),
    ("position", "nan-command", "column 'setpoint_rad' is not finite at data row 71"),
    ("force-blocks", "nan-output", "column 'motor_angle_rad' is not finite at data row 91"),
    ("force-blocks", "gap", "column 't_s' has a gap of 0.51 s at data row 121"),
    ("force-blocks", "short", "30 samples compared (at the fit's 50 Hz) is too few"),
])
def test_a_broken_sim_recording_is_refused_in_one_line(tmp_path, capsys, name, how, says
                                                        ) -> None:  # type: ignore[no-untyped-def]
    """A ``teleop sim`` recording with a command or output that is not a number where it is
    used, a gap, or too few samples: one line naming the file, column and row, exit 2 (it
    was diagnosed: a NaN command gave a nominal fit at its bounds and 'score -inf', three
    rows a ZeroDivisionError)."""
    from teleop.cli import main

    path = _corrupt(tmp_path, name, how)
    capsys.readouterr()
    assert main(["diagnose", str(path), "--model", "finger"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(path) in err[0] and says in err[0], err
