"""The robustness grid, the heat maps and the endurance machinery with synthetic runners."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from teleop.analysis.grasps import analyse_grasps
from teleop.analysis.stability import RunSignals
from teleop.analysis.sweep import SweepPoint, point_config
from teleop.analysis.sweep_endurance import run_endurance
from teleop.analysis.sweep_grid import REDUCED, GridSpec, format_grid, grid_points, run_grid
from teleop.analysis.sweep_heatmap import grid_matrix, plot_heatmaps
from teleop.analysis.sweep_objects import OBJECTS, object_name, with_object
from teleop.cli import main
from teleop.config import TeleopConfig
from teleop.errors import UserInputError

SMALL = GridSpec(("soft", "hard"), ("free-air", "block"), (0.0, 0.5), (0.0, 0.2),
                 (("none", 0.0), ("pareto", 0.01)), 4.0)


def fake_runner(cfg: TeleopConfig, duration_s: float) -> RunSignals:
    """Soft operators oscillate at 2 Hz beyond 0.1 s; contact (not free air) is felt at
    half its true force."""
    t = np.arange(0.0, duration_s, 1e-3)
    unstable = (cfg.master.virtual.style == "soft"
                and cfg.links.master_controller.delay_s > 0.1)
    sp = 0.5 * np.clip(t, 0, 1) + (0.1 * np.sin(2 * np.pi * 2 * t) if unstable else 0)
    true = (0.0 if cfg.hand.sim.object.kind == "none" else 4.0) * np.clip(t, 0, 1)
    return RunSignals(t_s=t, setpoint_rad=sp, finger_rad=sp, force_displayed_n=0.5 * true,
                      force_measured_n=true, energy_out_j=0 * t, energy_in_j=0 * t,
                      tank_j=np.ones((len(t), 1)), settle_s=1.0,
                      audit_margin_j=1.0 - (t if unstable else 0 * t))


def test_point_config_applies_operator_object_loss_and_pareto() -> None:
    p = SweepPoint("tdpa", 0.2, 0.01, 0.2, 5, "soft", "soft-cylinder", "pareto")
    cfg = point_config(TeleopConfig(), p)
    mc, ch = cfg.links.master_controller, cfg.links.controller_hand
    assert (mc.delay_s, mc.loss, mc.jitter, mc.jitter_s) == (0.2, 0.2, "pareto", 0.01)
    assert ch.loss == 0.2 and ch.delay_s == TeleopConfig().links.controller_hand.delay_s
    assert cfg.master.virtual.style == "soft" and cfg.controller.kind == "tdpa"
    o = cfg.hand.sim.object
    assert (o.kind, o.stiffness_n_per_m, o.damping_n_s_per_m) == ("cylinder", 300.0, 2.0)
    assert object_name(cfg) == "soft-cylinder"


def test_object_presets_round_trip() -> None:
    for name in OBJECTS:
        assert object_name(with_object(TeleopConfig(), name)) == name
    assert object_name(TeleopConfig()) == "stiff-cylinder"  # the config default
    with pytest.raises(UserInputError):
        with_object(TeleopConfig(), "sponge")
    crushable = with_object(TeleopConfig(), "crushable-cylinder").hand.sim.object
    assert crushable.yield_force_n == 5.0 and crushable.stiffness_n_per_m == 2000.0
    stiff = with_object(with_object(TeleopConfig(), "crushable-cylinder"), "stiff-cylinder")
    assert stiff.hand.sim.object.yield_force_n == 0.0  # a preset sets (and clears) the yield
    o = replace(TeleopConfig().hand.sim.object, yield_force_n=3.0)
    cfg = replace(TeleopConfig(), hand=replace(TeleopConfig().hand,
                                               sim=replace(TeleopConfig().hand.sim, object=o)))
    assert object_name(cfg) == "cylinder k=2000 c=5 yield=3"


def test_the_relaxed_operators_first_grasp_dents_the_crushable_cylinder_a_few_mm() -> None:
    """The preset's calibration (sweep_objects): the default loop's first grasp (its first 2 s:
    closed and held, the dent as deep as the whole 4.5 s grasp makes it: 4.1 mm), the physics
    engine's dents; the object keeps the plastic work (the audit's net)."""
    from services.lockstep import run_lockstep
    from sim.sim_hand import SimHand

    cfg = with_object(TeleopConfig(), "crushable-cylinder")
    hand = SimHand(cfg.hand)
    r = run_lockstep(cfg, 2.0, seed=1, hand=hand)
    dent = max(max(f.crush_m) for f in hand.state.fingers)
    assert 0.002 < dent < 0.008
    assert r.audit_environment_delivered_j[-1] - r.audit_environment_taken_j[-1] > 0.03


def test_grid_points_cover_every_axis_with_distinct_seeds() -> None:
    pts = grid_points(SMALL, ["two-layer", "direct"], seed=1)
    assert len(pts) == 2 * SMALL.size_per_controller == 64
    assert len({p.seed for p in pts}) == len(pts)
    assert {p.jitter for p in pts} == {"none", "pareto"}
    assert grid_points(SMALL, ["direct"], seed=1) != grid_points(SMALL, ["direct"], seed=2)
    with pytest.raises(UserInputError):
        grid_points(GridSpec(("soft",), ("sponge",), (0.0,), (0.0,), (("none", 0.0),), 1.0),
                    ["direct"], 0)


def test_grid_rows_and_heatmaps(tmp_path) -> None:
    seen: list[int] = []
    res = run_grid(TeleopConfig(), SMALL, ["two-layer"], fake_runner,
                   progress=lambda i, n, r: seen.append(n))
    assert len(res.runs) == 32 and seen == [32] * 32
    rows = json.loads(json.dumps(res.to_json(), default=str))["runs"]
    for row in rows:
        unstable = row["operator"] == "soft" and row["delay_s"] > 0.1
        assert row["stable"] is not unstable
        assert row["passive"] is not unstable and row["passive_audit"] is not unstable
        assert row["passive_ledger"] is True
        if row["object"] == "free-air":
            assert row["felt_true_force_ratio"] is None or np.isnan(row["felt_true_force_ratio"])
        else:
            assert row["felt_true_force_ratio"] == pytest.approx(0.5, rel=1e-3)
        assert {"finger1_rad", "displayed_force_n"} <= set(row["oscillation"])
        if unstable:
            assert row["oscillation_frequency_hz"] == pytest.approx(2.0, rel=0.1)
    m, rl, cl = grid_matrix(list(res.runs), "stable")
    assert m.shape == (4, 8) and len(rl) == 4 and len(cl) == 8
    assert m[rl.index("soft / block")].tolist() == [1, 0] * 4  # (loss, jitter, delay) cols
    paths = plot_heatmaps(res, tmp_path / "grid.png")
    assert [p.name for p in paths] == ["grid-two-layer.png"]
    assert paths[0].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    table = format_grid(res)
    assert "soft     block" in table and "2/8" not in table.split("\n")[2]


def test_reduced_grid_is_small() -> None:
    assert REDUCED.size_per_controller <= 8


def _fake_endurance(cfg: TeleopConfig, duration_s: float):  # noqa: ANN202
    """Grasps every 4.5 s whose peak pressure halves after the fifth beyond 0.5 s delay."""
    t = np.arange(0.0, duration_s, 1e-2)
    phase = np.fmod(t, 4.5)
    trig = np.where((phase > 0.5) & (phase < 3.5), 0.02, 0.0)
    k = np.floor(t / 4.5)
    weak = cfg.links.master_controller.delay_s > 0.5
    peak = np.where(weak & (k >= 5), 100.0, 200.0)
    p = np.zeros((len(t), 27))
    p[:, 4] = np.where(trig > 0, peak, 0.0)
    q = np.column_stack([trig * 20] * 3)
    s = RunSignals(t_s=t, setpoint_rad=q[:, 0], finger_rad=q[:, 0], force_displayed_n=trig,
                   force_measured_n=trig, energy_out_j=0 * t, energy_in_j=0 * t,
                   tank_j=np.ones((len(t), 1)))
    return s, analyse_grasps(t, trig, p, q, trig * 100, 0.005)


def test_endurance_rows_carry_the_weakest_grasp() -> None:
    res = run_endurance(TeleopConfig(), ["direct"], _fake_endurance, minutes=1.0,
                        delays_s=(0.0, 1.0))
    rows = {r["delay_s"]: r for r in res.to_json()["runs"]}
    assert rows[0.0]["endurance_min_grasp_ratio"] == pytest.approx(1.0)
    assert rows[1.0]["endurance_min_grasp_ratio"] == pytest.approx(0.5)
    assert rows[1.0]["grasp_count"] == 13 and len(rows[1.0]["grasps"]) == 13
    assert rows[1.0]["loss"] == 0.2


@pytest.mark.parametrize("argv, needle", [
    (["--grid", "full", "--endurance"], "--grid and --endurance: choose one"),
    (["--grid", "full", "--mode", "live"], "lockstep mode only"),
    (["--endurance", "--plot", "x.png"], "--plot: not available with --endurance"),
    (["--grid", "reduced", "--delays", "0,1"], "apply to the delay sweep only"),
    (["--endurance-minutes", "0", "--endurance"], "--endurance-minutes"),
    (["--grid", "huge"], "--grid"),
])
def test_bad_grid_and_endurance_input_is_one_line_exit_2(argv: list[str], needle: str,
                                                         capsys) -> None:
    try:
        status = main(["sweep", "--no-progress", *argv])
    except SystemExit as exc:  # argparse's own errors
        status = exc.code
    assert status == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0], err
