"""Live endurance check: ``teleop up`` for 50 s (three processes over zenoh on loopback),
then ``teleop grasps DIR`` on its recordings: every grasp of the virtual operator's repeated
script judged like the lockstep endurance (:func:`teleop.analysis.grasps.curl_grasps`), and no
energy store empty while the trigger is closed."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
from typing import Any

import pytest

pytestmark = [pytest.mark.network, pytest.mark.slow]

DURATION_S = 50.0  # 90 s, 75 s, 60 s until 2026-11-29 (CI's 20 minutes: 11 grasps, not 20)


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    rec = tmp_path_factory.mktemp("live") / "rec"
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    proc = subprocess.run(
        [sys.executable, "-m", "teleop.cli", "up", "--duration", f"{DURATION_S:g}",
         "--dashboard", "off", "--record", str(rec),
         "--set", f"zenoh.endpoint=tcp/127.0.0.1:{port}", "--set", f"session.name=live{port}"],
        capture_output=True, text=True, timeout=DURATION_S + 90)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    out = rec.parent / "grasps.json"  # one call: the report printed, its JSON written
    judged = subprocess.run([sys.executable, "-m", "teleop.cli", "grasps", str(rec), "--json",
                             str(out)], capture_output=True, text=True, timeout=60)
    print(judged.stdout)
    assert judged.returncode == 0, judged.stderr
    return dict(json.loads(out.read_text()))


def test_every_grasp_of_the_live_run_is_found(report: dict[str, Any]) -> None:
    assert report["grasp_count"] >= int(DURATION_S / 4.5) - 2  # a grasp every 4.5 s
    assert report["grasps"][0]["peak_pressure"] > 100  # the first grasp closed on the object


def test_every_live_grasp_holds_up_against_the_first(report: dict[str, Any]) -> None:
    """The loop must keep working: every grasp reaches 90 % of the first's peak pressure,
    closure and felt force (issue 13's floor).  A grasp during which a service's recording
    stopped for more than 0.25 s (the machine stalled that process: a stalled master's
    operator script jumps ahead) is not judged; at most two may be."""
    judged = [g for g in report["grasps"] if not g["interrupted"]]
    bad = [(g["grasp"], round(g["t_start_s"], 2), round(g["t_end_s"], 2),
            round(g["pressure_ratio"], 3), round(g["closure_ratio"], 3),
            round(g["felt_ratio"], 3))
           for g in judged if min(g["pressure_ratio"], g["felt_ratio"], g["closure_ratio"]) < 0.9]
    context = f"run {report['duration_s']:.1f} s, recording gaps {report['gaps']}"
    assert not bad, (f"weak grasps (index, start s, end s, pressure, closure, felt over the "
                     f"first): {bad}; {context}")
    assert len(report["grasps"]) - len(judged) <= 2, context


def test_no_store_sits_empty_while_the_operator_squeezes(report: dict[str, Any]) -> None:
    """No tank or store empty while the trigger is closed (issue 13): none longer than the
    start-up before the first touch, none for more than 1 % of the squeezing time (a spell
    during a recording gap or 0.5 s after it is reported apart: a stalled process)."""
    assert {e["store"] for e in report["empty"]} == {"master tank", "hand tank",
                                                     "controller store"}
    for e in report["empty"]:
        assert e["closed_s"] > 0.3 * DURATION_S, e
        assert e["longest_s"] <= 1.5 and e["empty_fraction"] <= 0.01, e


def test_the_live_run_is_passive_by_the_physics(report: dict[str, Any]) -> None:
    """The physical audit of the recordings (the virtual operator's work at the trigger and
    the fingers' on the object, against the tanks' initial energy; not the controllers'
    books) never goes below zero, and real work was done at both ports (a grasp every
    4.5 s: 0.24 J taken at the trigger in 25 s, measured 2026-11-29)."""
    a = report["energy_audit"]
    assert a["audited"] and a["passive"], a
    assert a["min_margin_j"] >= -a["tolerance_j"], a
    assert a["operator_taken_j"] > 0.2 and a["environment_delivered_j"] > 0.2, a
