"""The soak's verdict from logs written by the services' own writer (synthetic values): a
crash, an unrecovered fault, a flood not rejected or an audit deficit each fail it."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from services.soak import Fault, SoakRun
from services.soak_log import SoakLog
from services.soak_summary import summarise
from teleop.config import load_config


def _write(work: Path, role: str, pid: int, *, deficit: bool = False,
           stuck_after_s: float = 99.0) -> None:
    log = SoakLog(work, role, pid, epoch_s=100.0, rate_hz=100.0)
    for k in range(3000):  # 30 s at 100 Hz: status lines at 10 Hz
        t = 100.0 + k / 100.0
        log.timing(t, 1e-4, 0.0)
        if log.due():
            rel = t - 100.0
            # every watchdog trips during a fault (and stays tripped after ``stuck_after_s``)
            wd = 1.0 if 10.0 <= rel < 11.5 or rel >= stuck_after_s else 0.0
            rejects = 0 if rel < 20.0 or role == "master" else 3000  # a flood at 20 s
            audit = None
            if role in ("master", "hand"):
                out = (0.2 if deficit and role == "master" else 0.01) * rel
                audit = (out, 0.02 * rel)
            extra = {"trigger_m": 0.02 if int(rel) % 4 < 2 else 0.0} if role == "master" else {}
            log.status(t, wd, rejects, 1.0, audit, **extra)
    log.close()


@pytest.fixture
def run(tmp_path: Path) -> SoakRun:
    for pid, role in enumerate(("master", "controller", "hand")):
        _write(tmp_path, role, pid + 1)
    r = SoakRun(tmp_path, epoch=100.0, start_s=0.0, duration_s=30.0)
    r.faults = [Fault("controller_restart", "controller", 10.0, 11.0),
                Fault("malformed_flood", "hand+controller", 20.0, 23.0, injected=6000)]
    r.samples = [(float(t), role, pid, 50.0, 10) for t in range(0, 30, 5)
                 for pid, role in enumerate(("master", "controller", "hand"))]
    return r


def _doc(run: SoakRun, **kw: object) -> dict:
    return summarise(run, load_config(None, []), {"master": 0, "controller": 0, "hand": 0},
                     [], minutes=0.5, fault_every_s=10.0, interrupted=False, **kw)


def test_a_clean_run_passes_and_says_so_in_one_line(run: SoakRun) -> None:
    doc = _doc(run)
    assert doc["ok"], doc["verdict"]
    assert doc["faults"][0]["recovery_s"] == pytest.approx(0.5, abs=0.11)
    assert doc["faults"][1]["rejected"] == 6000  # 3000 at the hand + 3000 at the controller
    assert doc["energy_audit"]["violations"] == 0 and doc["grasps"]["closures"] >= 5
    assert doc["verdict"].startswith("soak PASS") and "\n" not in doc["verdict"]
    assert not doc["growth_judged"]  # half a minute: growth reported, not judged


def test_each_failure_fails_the_verdict(run: SoakRun, tmp_path: Path) -> None:
    crashed = replace(run, crashes=["hand exited with 1 at 12.0 s"])
    assert not _doc(crashed)["ok"] and "1 crashes" in _doc(crashed)["verdict"]
    short = replace(run, faults=[*run.faults[:1], replace(run.faults[1], injected=10_000)])
    assert not _doc(short)["ok"]  # 6000 of 10000 rejected
    for p in tmp_path.glob("master-*"):
        p.unlink()
    _write(tmp_path, "master", 1, deficit=True)  # the operator gets more than was put in
    doc = _doc(run)
    assert doc["energy_audit"]["violations"] > 0 and not doc["ok"]
    for p in tmp_path.glob("*-*.*"):
        p.unlink()
    for pid, role in enumerate(("master", "controller", "hand")):
        _write(tmp_path, role, pid + 1, stuck_after_s=25.0 if role == "hand" else 99.0)
    stuck = replace(run, faults=[Fault("link_cut", "hand", 24.0, 25.0)])
    doc = _doc(stuck)  # the hand's watchdog never clears after the cut
    assert doc["faults"][0]["recovery_s"] is None and doc["faults_unrecovered"] == 1
    assert not doc["ok"] and "1 unrecovered" in doc["verdict"]


def test_each_process_reports_its_heap_trims_from_its_own_status_lines(tmp_path: Path) -> None:
    for pid, role in enumerate(("master", "controller", "hand")):
        _write(tmp_path, role, pid + 1)
    log = SoakLog(tmp_path, "controller", 7, epoch_s=100.0, rate_hz=10.0)  # a restarted one
    for k, trims in enumerate((0.0, 1.0, 1.0, 2.0)):
        log.status(100.0 + k / 10.0, 0.0, 0, 1.0, None, heap_trims=trims, heap_trim_max_ms=1.5)
    log.close()
    r = SoakRun(tmp_path, epoch=100.0, start_s=0.0, duration_s=30.0)
    r.samples = [(float(t), role, pid, 50.0, 10) for t in range(0, 30, 5)
                 for role, pid in (("master", 1), ("controller", 7))]
    procs = {p["pid"]: p for p in _doc(r)["processes"]}
    assert procs[7]["heap_trims"] == 2.0 and procs[7]["heap_trim_max_ms"] == 1.5
    assert procs[1]["heap_trims"] == 0.0  # the master's lines carry none
