"""``teleop diagnose`` on the command line: JSON contract, plot, bad input (exit 2, one line)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from teleop.cli import main
from teleop.diagnose.model import parse_nominal
from teleop.diagnose.synth import INPUT_COL, OUTPUT_COL, make_case, make_validation
from teleop.errors import UserInputError
from teleop.recording import Recording, write_recording


def _case_files(tmp_path: Path, effects: tuple[str, ...]) -> tuple[Path, Path, str]:
    case = make_case(effects, "random", seed=4242, duration_s=4.0)
    val = make_validation(case, "steps", seed=4343, duration_s=4.0)
    write_recording(tmp_path / "rec.csv", case.recording)
    write_recording(tmp_path / "val.csv", val.recording)
    p = case.params
    return tmp_path / "rec.csv", tmp_path / "val.csv", (f"inertia={p.inertia},viscous,"
                                                         f"stiffness={p.stiffness}")


def test_json_contract_plot_and_validation(tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    rec, val, nominal = _case_files(tmp_path, ("coulomb_friction",))
    out_json, out_png = tmp_path / "d.json", tmp_path / "d.png"
    code = main(["diagnose", str(rec), "--model", "axis", "--nominal", nominal,
                 "--tolerance", "0.1", "--input", INPUT_COL, "--output", OUTPUT_COL,
                 "--validate", str(val), "--json", str(out_json), "--plot", str(out_png)])
    assert code == 0
    doc = json.loads(out_json.read_text())
    assert doc["effects"][0]["name"] == "coulomb_friction"
    assert set(doc["effects"][0]) >= {"name", "params", "delta_bic"}
    assert doc["effects"][0]["delta_bic"] > 0
    assert all(set(w) >= {"t_start_s", "t_end_s", "why"} for w in doc["windows"])
    assert doc["fit"]["after"]["nrmse"] < doc["fit"]["before"]["nrmse"]
    assert doc["validation"]["after"]["nrmse"] < doc["validation"]["before"]["nrmse"]
    assert doc["analysis"] in ("output-error", "equation-error")
    assert out_png.stat().st_size > 10_000 and out_png.read_bytes()[:4] == b"\x89PNG"
    assert "coulomb_friction" in capsys.readouterr().out


def test_json_to_stdout_is_pure_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rec, _, nominal = _case_files(tmp_path, ())
    assert main(["diagnose", str(rec), "--nominal", nominal, "--tolerance", "0.1",
                 "--input", INPUT_COL, "--output", OUTPUT_COL, "--json", "-"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["effects"] == []


def _write(path: Path, t: np.ndarray, y: np.ndarray) -> Path:
    write_recording(path, Recording.from_columns({"t_s": t, "angle_rad": y}))
    return path


NAMED = {"missing column": ("'theta_rad'",), "not increasing": ("t_s", "row"),
         "nan gap": ("'angle_rad'", "row 100"), "too short": ("'t_s'",),
         "time gap": ("'t_s'", "row 1001"), "input never moves": ("'u_nm'", "every row")}
"""What the one line must name (column, row) where the problem has them."""


@pytest.mark.parametrize("problem", ["missing file", "missing column", "not increasing",
                                     "nan gap", "too short", "flat", "bad nominal", "time gap",
                                     "input never moves"])
def test_bad_input_is_one_line_and_exit_2(problem: str, tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    t = np.arange(2000) / 1000.0
    y = np.sin(2 * np.pi * t)
    path = tmp_path / "r.csv"
    args = ["--output", "angle_rad", "--nominal", "viscous,stiffness"]
    if problem == "missing file":
        path = tmp_path / "nope.csv"
    elif problem == "missing column":
        _write(path, t, y)
        args = ["--output", "theta_rad", "--nominal", "viscous,stiffness"]
    elif problem == "not increasing":
        _write(path, t, y)
        text = path.read_text().replace("\n0.005,", "\n0.003,", 1)
        path.write_text(text)
    elif problem == "nan gap":
        _write(path, t, y)
        lines = path.read_text().splitlines()
        lines[100] = lines[100].split(",")[0] + ","
        path.write_text("\n".join(lines) + "\n")
    elif problem == "too short":
        _write(path, t[:50], y[:50])
    elif problem == "time gap":
        _write(path, np.where(t >= 1.0, t + 0.5, t), y)
    elif problem == "flat":
        _write(path, t, np.zeros_like(t))
    elif problem == "bad nominal":
        _write(path, t, y)
        args = ["--output", "angle_rad", "--nominal", "viscous,springiness"]
    elif problem == "input never moves":  # (the equation-error path divided by its spread)
        write_recording(path, Recording.from_columns({"t_s": t, "u_nm": np.zeros_like(t),
                                                      "angle_rad": y}))
        args = [*args, "--input", "u_nm"]
    code = main(["diagnose", str(path), *args])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and err.startswith("teleop diagnose: error:")
    assert all(w in err for w in NAMED.get(problem, ())), err


def test_parse_nominal_values_and_bounds() -> None:
    n = parse_nominal("inertia=2, viscous ,stiffness=100", tolerance=0.1)
    assert n.terms == ("inertia", "viscous", "stiffness")
    assert n.bounds("inertia") == pytest.approx((1.8, 2.2))
    assert n.bounds("viscous") == (0.0, float("inf"))
    with pytest.raises(UserInputError):
        parse_nominal("viscous,viscous")
    with pytest.raises(UserInputError):
        parse_nominal("inertia=-1")


def _pd_loop(c: float, dist_scale: float, seed: int) -> Recording:
    """A PD-controlled integrating axis (J=1, b=0.5) with Coulomb friction ``c`` and a
    random-walk disturbance effort that is not recorded."""
    rng = np.random.default_rng(seed)
    dt, n = 1e-3, 6000
    t = np.arange(n) * dt
    ref = 0.5 * np.sin(2 * np.pi * 0.4 * t) + 0.3 * np.sin(2 * np.pi * 1.3 * t)
    dist = np.cumsum(rng.standard_normal(n)) * dist_scale
    x = v = 0.0
    xs, us = np.empty(n), np.empty(n)
    for i in range(n):
        u = 100.0 * (ref[i] - x) - 10.0 * v
        a = u + dist[i] - 0.5 * v - c * np.tanh(v / 0.01)
        v += a * dt
        x += v * dt
        xs[i], us[i] = x, u
    y = xs + 2e-5 * rng.standard_normal(n)
    return Recording.from_columns({"t_s": t, "torque_nm": us, "angle_rad": y})


def test_equation_error_finds_friction_in_closed_loop_data() -> None:
    from teleop.diagnose.diagnose import DiagnoseOptions, diagnose
    from teleop.diagnose.model import AxisNominal

    d = diagnose([_pd_loop(3.0, 0.0, 5)], DiagnoseOptions(
        AxisNominal(("inertia", "viscous"), (1.0, None), 0.1), "torque_nm", "angle_rad",
        analysis="equation-error"), validate=_pd_loop(3.0, 0.0, 7))
    assert d.analysis == "equation-error"
    assert d.effects and d.effects[0].name == "coulomb_friction"
    assert abs(d.effects[0].params[0][1] - 3.0) < 0.3
    # all its physics is in the catalog: no library term beside the Coulomb level (with the
    # library offered after it, u(t - 0.1 s) and v|v| were kept here while the equation error
    # was inconsistent: input one filter pass from the physics against the position columns'
    # two, input misaligned by a sample; residual 15.6x its noise, now 1.0x)
    assert d.proposed == (), d.proposed
    assert d.residual_after.rms_over_noise < 2.0, d.residual_after
    assert d.nrmse_after < 0.5 * d.nrmse_before
    assert d.validation is not None
    assert d.validation.nrmse_after < 0.5 * d.validation.nrmse_before


def test_a_drifting_simulation_switches_to_equation_error() -> None:
    from teleop.diagnose.diagnose import DiagnoseOptions, diagnose
    from teleop.diagnose.model import AxisNominal

    rec = _pd_loop(3.0, 3.0, 6)  # a large unrecorded disturbance: replaying the effort drifts
    d = diagnose([rec], DiagnoseOptions(AxisNominal(("inertia", "viscous"), (1.0, None), 0.1),
                                        "torque_nm", "angle_rad"))
    assert d.analysis == "equation-error" and "drifts" in d.analysis_reason
