"""Ctrl-C during a sweep: the finished runs are reported and written, not lost.

A full grid or an endurance sweep runs for many minutes; before, an interrupt dropped every
finished run with it.  Now the delay sweep, the grid and the endurance sweep return what was
done (``SweepResult.interrupted``, a note saying how many of how many), the command prints the
table, writes the JSON and plot, and exits 130.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from ctrl_c import interrupt_when
from test_sweep import fake_runner
from test_sweep_grid import SMALL, _fake_endurance
from test_sweep_grid import fake_runner as grid_runner

from teleop.analysis.sweep import run_delay_sweep
from teleop.analysis.sweep_endurance import run_endurance
from teleop.analysis.sweep_grid import format_grid, grid_points, run_grid
from teleop.analysis.sweep_report import format_table, result_from_json
from teleop.config import TeleopConfig


def _kept(work):  # noqa: ANN001, ANN202
    """``work()``, failing the test (not the session) if the interrupt escapes it."""
    try:
        return work()
    except KeyboardInterrupt:
        pytest.fail("the interrupt escaped: the finished runs were lost")


class _StopAt:
    """A runner that raises KeyboardInterrupt (as Ctrl-C does) on its ``n``-th call."""

    def __init__(self, runner, n: int) -> None:  # noqa: ANN001
        self.runner, self.n, self.calls = runner, n, 0

    def __call__(self, cfg: TeleopConfig, duration_s: float):  # noqa: ANN204
        self.calls += 1
        if self.calls == self.n:
            raise KeyboardInterrupt
        return self.runner(cfg, duration_s)


def test_an_interrupted_delay_sweep_keeps_its_finished_runs() -> None:
    res = _kept(lambda: run_delay_sweep(TeleopConfig(), [0.0, 0.02, 0.05, 0.1], [0.0, 0.2],
                                        ["two-layer", "direct"], duration_s=2.0,
                                        refine_steps=4, runner=_StopAt(fake_runner, 6)))
    assert res.interrupted and len(res.runs) == 5
    assert "interrupted (Ctrl-C) after 5 of 24 runs" in res.notes[-1]
    doc = json.loads(json.dumps(res.to_json()))
    assert doc["interrupted"] is True and len(doc["runs"]) == 5
    assert result_from_json(doc).interrupted  # read back as what it is
    assert "interrupted" in format_table(res)


def test_a_sweep_interrupted_in_its_bisection_keeps_the_steps_done() -> None:
    # 16 grid runs; direct's zero-loss ones go first, then its bisection steps
    whole = run_delay_sweep(TeleopConfig(), [0.0, 0.02, 0.05, 0.1], [0.0, 0.2],
                            ["two-layer", "direct"], duration_s=2.0, refine_steps=4,
                            runner=fake_runner)
    assert not whole.interrupted and whole.to_json()["interrupted"] is False
    order = _kept(lambda: run_delay_sweep(TeleopConfig(), [0.0, 0.02, 0.05, 0.1], [0.0, 0.2],
                                          ["two-layer", "direct"], duration_s=2.0,
                                          refine_steps=4, runner=_StopAt(fake_runner, 12)))
    assert order.interrupted and len(order.runs) == 11
    refined = [r for r in order.runs if r.refine]
    assert refined, "no bisection step was done before the interrupt"
    lo, hi = dict((c, (a, b)) for c, a, b in order.measured_bracket_s)["direct"]
    assert lo < hi and hi - lo < 0.03  # narrowed by the steps it did


def test_an_interrupted_grid_and_endurance_keep_theirs_in_point_order() -> None:
    res = _kept(lambda: run_grid(TeleopConfig(), SMALL, ["two-layer"], _StopAt(grid_runner, 8)))
    assert res.interrupted and len(res.runs) == 7 and "after 7 of 32" in res.notes[-1]
    points = grid_points(SMALL, ["two-layer"], 0)
    assert [r.point for r in res.runs] == points[:7]
    assert "interrupted" in format_grid(res)
    end = _kept(lambda: run_endurance(TeleopConfig(), ["direct"], _StopAt(_fake_endurance, 2),
                                      minutes=0.5, delays_s=(0.0, 1.0)))
    assert end.interrupted and [r.point.delay_s for r in end.runs] == [0.0]


def test_ctrl_c_on_teleop_sweep_writes_the_finished_runs_and_exits_130(tmp_path: Path) -> None:
    """The real command, its spawned workers, and Ctrl-C as a terminal sends it (SIGINT to
    the whole process group) once two runs are done."""
    out = tmp_path / "sweep.json"

    def two_done(err: str) -> bool:
        return max((int(m) for m in re.findall(r" (\d+)/12 ", err)), default=0) >= 2

    code, _, err = interrupt_when(
        ["sweep", "--jobs", "2", "--duration", "1", "--delays", "0,0.01,0.02,0.05,0.1,0.2",
         "--losses", "0", "--controllers", "two-layer,direct", "--refine", "0",
         "--json", str(out)], two_done)
    assert code == 130, err[-500:]
    assert "interrupted; the" in err.splitlines()[-1]
    doc = json.loads(out.read_text())
    assert doc["interrupted"] is True and 2 <= len(doc["runs"]) < 12
    assert any("interrupted (Ctrl-C)" in n for n in doc["notes"])
