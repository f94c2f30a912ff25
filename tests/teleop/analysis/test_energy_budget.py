"""Per-grasp energy budget: the pure split on synthetic arrays, and the command end to end."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from teleop.analysis.energy_budget import grasp_budget


def _fake(n: int = 901) -> SimpleNamespace:
    t = np.linspace(0.0, 9.0, n)
    ramp = t / 9.0  # everything cumulative grows linearly over the run
    z = np.zeros(n)
    return SimpleNamespace(
        t_s=t, audit_operator_delivered_j=0.3 * ramp, audit_operator_taken_j=0.1 * ramp,
        audit_environment_delivered_j=0.02 * ramp, audit_environment_taken_j=z,
        hand_port_out_j=9.0 * ramp, hand_port_in_j=3.0 * ramp, master_port_out_j=0.3 * ramp,
        master_port_in_j=0.1 * ramp, master_tank_j=z + 1.0, controller_store_j=z,
        hand_tank_j=10.0 - 6.0 * ramp, pressure=np.tile(np.arange(27.0), (n, 1)))


def test_cycles_split_the_cumulative_flows() -> None:
    rows = grasp_budget(_fake(), 3.0)
    assert [b.index for b in rows] == [1, 2, 3]
    for b in rows:  # one third of each total per 3 s cycle (to the sample grid)
        assert math.isclose(b.operator_net_j, 0.2 / 3, rel_tol=0.02)
        assert math.isclose(b.object_net_j, 0.02 / 3, rel_tol=0.02)
        assert math.isclose(b.hand_ledger_net_j, 2.0, rel_tol=0.02)
        assert math.isclose(b.stores_change_j, -2.0, rel_tol=0.02)
        assert b.peak_pressure == 26.0


def test_the_table_ends_with_the_weakest_grasp_and_the_first_against_the_next_three() -> None:
    from teleop.analysis.energy_budget import GraspBudget, format_budget

    def row(k: int, peak: float) -> GraspBudget:
        return GraspBudget(k, 4.5 * k, 4.5 * k + 4.5, 0.0, 0.0, 0.0, 0.0, 0.0, peak)

    peaks = (226.0, 180.0, 186.0, 186.0, 191.0, 190.0)  # the soft operator's block at 100 ms
    text = format_budget(tuple(row(k + 1, p) for k, p in enumerate(peaks)))
    assert "weakest over the first (peak pressure): 0.80" in text
    assert ("after the first (peak pressure): the best of the next 3 0.82 of the first; "
            "the weakest later grasp (grasp 6) 1.02 of that best") in text
    short = format_budget(tuple(row(k + 1, 600.0) for k in range(3)))
    assert "after the first" not in short and "weakest over the first (peak pressure): 1.00" \
        in short
    # a cycle without samples (a nan peak) is said, not silently passed over (as min() did)
    for holes in ((226.0, float("nan"), 180.0), (226.0, 180.0, float("nan"))):
        text = format_budget(tuple(row(k + 1, p) for k, p in enumerate(holes)))
        assert ("weakest over the first (peak pressure): 0.80 (1 of 3 cycles without "
                "pressure samples)") in text, text


def test_bad_cycle_is_refused() -> None:
    with pytest.raises(ValueError):
        grasp_budget(_fake(), 0.0)


@pytest.mark.parametrize("obj, costs", [("none", False), ("cylinder", True)])
def test_command_free_air_costs_nothing_a_grasp_costs(obj: str, costs: bool) -> None:
    out = subprocess.run([sys.executable, "-m", "teleop.cli", "budget", "--seconds", "9.2",
                          "--set", f"hand.sim.object.kind={obj}", "--json", "-"],
                         capture_output=True, text=True, timeout=300, check=True)
    doc = json.loads(out.stdout)
    g = doc["grasps"][1]
    if costs:
        assert g["object_net_j"] > 1e-4 and g["peak_pressure"] > 100
    else:  # no object: no port work, and the free-motion refund returns the servo's work
        assert g["object_net_j"] == 0.0
        assert abs(g["stores_change_j"]) < 0.05


def test_command_refuses_a_bad_key() -> None:
    out = subprocess.run([sys.executable, "-m", "teleop.cli", "budget", "--set", "nope=1"],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1
