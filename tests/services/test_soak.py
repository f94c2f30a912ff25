"""``teleop faults --soak``: the CI version (one minute, live, real zenoh, three processes),
and its user errors."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest


def _cli(*args: str, timeout: float = 60.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "teleop.cli", "faults", *args],
                          capture_output=True, text=True, timeout=timeout)


@pytest.mark.parametrize("args, what", [
    (("--soak", "1", "--mode", "live"), "--soak"),
    (("--soak", "1", "--fault-every", "3"), "--fault-every 3"),
    (("--soak", "0"), "--soak"),
])
def test_soak_user_errors_are_one_line_exit_2(args: tuple[str, ...], what: str) -> None:
    p = _cli(*args)
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert what in lines[-1] and "Traceback" not in p.stderr


@pytest.mark.slow
def test_a_45_s_soak(tmp_path: Path) -> None:
    """45 s with a fault every 12 s: the controller killed, a link cut, a malformed flood
    (one minute until 2026-11-29: CI's 20 minutes)."""
    out = tmp_path / "soak.json"
    p = _cli("--soak", "0.75", "--fault-every", "12", "--json", str(out), timeout=240.0)
    doc = json.loads(out.read_text())
    assert doc["crashes"] == [], doc["crashes"]  # must be none, loaded machine or not
    assert p.returncode == (0 if doc["ok"] else 1)
    assert p.stdout.strip().splitlines()[-1] == doc["verdict"]
    assert "1/1 min" not in p.stderr or "faults" in p.stderr  # progress lines on stderr
    kinds = [f["kind"] for f in doc["faults"]]
    assert kinds[:3] == ["controller_restart", "link_cut", "malformed_flood"], kinds
    for f in doc["faults"]:  # every fault recovered: all three watchdogs clear again
        assert f["recovery_s"] is not None and f["recovery_s"] < 20.0, f
        if f["kind"] == "malformed_flood":
            assert f["injected"] > 0 and f["rejected"] >= 0.9 * f["injected"], f
    assert doc["grasps"]["closures"] >= 5 and doc["grasps"]["contact_episodes"] >= 3
    a = doc["energy_audit"]
    assert a["audited"] and a["violations"] == 0 and a["samples"] > 300
    roles = {pr["role"] for pr in doc["processes"]}
    assert roles == {"master", "controller", "hand"}
    # two controller processes at least: the killed one and its successor
    assert sum(pr["role"] == "controller" for pr in doc["processes"]) >= 2
    for w in doc["latency"]:
        for role in ("master", "controller", "hand"):
            x = w[role]
            assert x["ticks"] > 0 and x["max_us"] >= x["p99_us"] >= x["p50_us"]
            assert x["stalls"] >= 0
    assert doc["load_avg"] and doc["cpus"]
