"""The sweep machinery with a synthetic runner (the real loop is in test_sweep_lockstep.py)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from teleop.analysis.stability import RunSignals
from teleop.analysis.sweep import max_stable_delay, point_config, run_delay_sweep
from teleop.analysis.sweep_report import format_table
from teleop.config import TeleopConfig
from teleop.errors import UserInputError

LIMIT_S = 0.0333


def fake_runner(cfg: TeleopConfig, duration_s: float) -> RunSignals:
    """'direct' oscillates with growing amplitude beyond LIMIT_S; noise seeded per point."""
    d = cfg.links.master_controller.delay_s
    t = np.arange(0.0, duration_s, 1e-3)
    rng = np.random.default_rng(cfg.session.seed)
    rate = 1.5 if (cfg.controller.kind == "direct" and d > LIMIT_S) else -1.5
    osc = np.clip(0.02 * np.exp(rate * t), 0, 1.0) * np.sin(2 * np.pi * 5 * t)
    sp = 1.5 * (1 - np.cos(np.pi * np.minimum(t, 1.0))) + osc
    noise = 1e-4 * rng.standard_normal(len(t))
    e_in = np.linspace(0, 1, len(t))
    extra = 0.1 * t if cfg.controller.kind == "direct" and d > 0 else 0 * t
    return RunSignals(t_s=t, setpoint_rad=sp, finger_rad=sp + noise, force_displayed_n=sp,
                      force_measured_n=sp, energy_out_j=e_in + extra, energy_in_j=e_in,
                      tank_j=np.ones((len(t), 1)), limited_count=3, steps=len(t))


def test_point_config_applies_point() -> None:
    from teleop.analysis.sweep import SweepPoint

    cfg = point_config(TeleopConfig(), SweepPoint("direct", 0.2, 0.01, 0.2, 42))
    link = cfg.links.master_controller
    assert (link.delay_s, link.loss, link.jitter, link.jitter_s) == (0.2, 0.2, "uniform", 0.01)
    assert link.backward_delay_s is None
    assert cfg.controller.kind == "direct" and cfg.session.seed == 42


def test_sweep_classifies_and_bisects() -> None:
    seen: list[int] = []
    res = run_delay_sweep(TeleopConfig(), [0.0, 0.02, 0.05, 0.1], [0.0, 0.2],
                          ["two-layer", "direct"], duration_s=3.0, refine_steps=4, runner=fake_runner,
                          progress=lambda i, n, r: seen.append(i),
                          predicted=[("direct", 0.03)])
    grid = res.grid_runs()
    assert len(grid) == 16
    assert all(r.metrics.stable and r.metrics.passive for r in grid
               if r.point.controller == "two-layer")
    direct = {r.point.delay_s: r.metrics for r in grid
              if r.point.controller == "direct" and r.point.loss == 0}
    assert direct[0.0].stable and direct[0.02].stable
    assert not direct[0.05].stable and not direct[0.1].stable
    assert direct[0.0].passive and not direct[0.02].passive
    lo, hi = dict((c, (a, b)) for c, a, b in res.measured_bracket_s)["direct"]
    assert lo <= LIMIT_S < hi and hi - lo == pytest.approx(0.03 / 16)
    assert seen == list(range(1, len(res.runs) + 1))
    doc = json.loads(json.dumps(res.to_json()))
    assert doc["predicted_max_stable_delay_s"] == {"direct": 0.03}
    assert math.isclose(doc["measured_max_stable_delay_s"]["direct"], lo)
    row = doc["runs"][0]
    for key in ("controller", "delay_s", "jitter_s", "loss", "stable", "passive",
                "energy_generated_j", "tracking_rms_rad", "force_rms_n", "tank_min_j"):
        assert key in row
    table = format_table(res)
    assert "measured/predicted" in table and "direct" in table


def test_the_table_says_when_no_run_at_loss_0_measured_the_largest_stable_delay() -> None:
    """A sweep without loss 0 measures no largest stable delay: the table says so, and
    keeps "unstable at every delay" for a controller that was (it read "unstable at every
    delay" for both controllers of a `--losses 0.05` sweep whose every run was stable)."""
    lossy = run_delay_sweep(TeleopConfig(), [0.0, 0.02], [0.2], ["two-layer", "direct"],
                            duration_s=2.0, runner=fake_runner)
    assert all(r.metrics.stable for r in lossy.runs)
    lines = format_table(lossy).splitlines()
    for c in ("two-layer", "direct"):
        line = next(x for x in lines if x.startswith(f"  {c} "))
        assert line.split() == [c, "not", "measured", "(no", "run", "at", "loss", "0)"] or (
            line.split()[:8] == [c, "not", "measured", "(no", "run", "at", "loss", "0);"]), line
    unstable = run_delay_sweep(TeleopConfig(), [0.05, 0.1], [0.0], ["direct"],
                               duration_s=2.0, runner=fake_runner)
    assert "direct     measured unstable at every delay" in format_table(unstable)


def test_max_stable_delay_needs_all_below_stable() -> None:
    res = run_delay_sweep(TeleopConfig(), [0.0, 0.01, 0.2], [0.0], ["direct"],
                          duration_s=2.0, runner=fake_runner)
    assert max_stable_delay(res.runs, "direct") == (0.01, 0.2)
    lo, hi = max_stable_delay(res.runs, "two-layer")  # no such runs
    assert math.isnan(lo) and math.isinf(hi)


def test_spawn_pool_is_deterministic() -> None:
    args = (TeleopConfig(), [0.0, 0.05], [0.0, 0.2], ["direct"])
    serial = run_delay_sweep(*args, duration_s=1.5, seed=3, runner=fake_runner)
    pooled = run_delay_sweep(*args, duration_s=1.5, seed=3, workers=2, runner=fake_runner)
    def rows(res: object) -> list[str]:  # JSON text: nan compares equal to nan
        return [repr({k: v for k, v in r.row().items() if k != "wall_s"}) for r in res.runs]

    assert rows(serial) == rows(pooled)


def test_bad_grid_is_user_error() -> None:
    with pytest.raises(UserInputError):
        run_delay_sweep(TeleopConfig(), [], [0.0], ["direct"], runner=fake_runner)
    with pytest.raises(UserInputError):
        run_delay_sweep(TeleopConfig(), [0.1], [1.5], ["direct"], runner=fake_runner)


def test_plot_writes_png(tmp_path) -> None:
    from teleop.analysis.sweep_plot import plot_sweep

    res = run_delay_sweep(TeleopConfig(), [0.0, 0.05], [0.0, 0.2],
                          ["two-layer", "direct"], duration_s=1.5, predicted=[("direct", 0.03)],
                          runner=fake_runner)
    out = plot_sweep(res, tmp_path / "s.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_rerun_log_has_metrics_and_signals(tmp_path) -> None:
    import rerun as rr

    from teleop.analysis.sweep_rerun import log_sweep

    res = run_delay_sweep(TeleopConfig(), [0.0, 0.05], [0.0], ["direct"],
                          duration_s=1.0, keep_signals=True, runner=fake_runner)
    assert res.runs[0].signals is not None and len(res.runs[0].signals.t_s) == 200
    path = log_sweep(res, tmp_path / "s.rrd")
    entities = {ch.entity_path for ch in rr.chunk.RrdReader(str(path)).stream()}
    assert "/metrics/direct/loss_0/stable" in entities
    assert "/signals/direct/loss_0/delay_50ms/force_displayed_n" in entities
