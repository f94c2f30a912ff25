"""The short fault suite (what CI runs) and the watchdog behaviour it relies on, in lockstep.

For every scenario: the hand stays inside its joint limits, never moves on invalid data, the
energy balance holds, the services recover, nothing crashes.
"""

from __future__ import annotations

import json
import logging
from dataclasses import fields, replace

import numpy as np
import pytest

from services import faults as F
from services.faults import BASE_OVERRIDES, SuiteResult, run_suite
from services.lockstep import LockstepResult, run_lockstep
from teleop.analysis.faults import FLOOD_KINDS, held_still, recovery_time_s
from teleop.cli import main
from teleop.config import TeleopConfig, load_config
from tests.teleop.control.two_layer_parts import patch_sides


@pytest.fixture(scope="module")
def cfg() -> TeleopConfig:
    return load_config(None, list(BASE_OVERRIDES))


@pytest.fixture(scope="module")
def suite(cfg: TeleopConfig) -> SuiteResult:
    logging.getLogger("teleop.transport").setLevel(logging.ERROR)
    try:
        return run_suite(cfg, short=True)
    finally:
        logging.getLogger("teleop.transport").setLevel(logging.NOTSET)


def _by_name(suite: SuiteResult) -> dict[str, F.ScenarioResult]:
    return {r.name: r for r in suite.results}


def test_every_scenario_passes_every_check(suite: SuiteResult) -> None:
    names = [r.name for r in suite.results]
    assert names == ["controller_restart", "link_cut", "master_link_cut", "burst_loss",
                     "dup_reorder_storm", "malformed_flood", "serial_faults"]
    for r in suite.results:
        assert r.ok, (r.name, r.failures)
        assert not r.crashed
        assert r.joint_limit_violations == 0 and r.applied_commands > 100
        assert r.energy_violations == 0
        assert r.min_energy_margin_j >= 0.0 or r.name == "serial_faults"  # hand-only: ledger
        assert 0.0 <= r.recovery_s <= F.RECOVERY_MAX_S, r.name
        assert not r.moved_on_invalid


def test_the_flood_is_rejected_by_reason_and_moves_nothing(suite: SuiteResult) -> None:
    r = _by_name(suite)["malformed_flood"]
    assert r.injected == 2000  # 1000 into the hand, 1000 into the controller
    assert r.rejected == r.injected
    reasons = dict(r.rejects_by_reason)
    for _, reason in FLOOD_KINDS:
        if reason != "*":
            assert reasons.get(reason, 0) > 0, reason
    assert r.recovery_s == 0.0  # it never left the baseline (bit-identical set-points)


def test_watchdogs_trip_on_outages_and_storms_are_filtered(suite: SuiteResult) -> None:
    res = _by_name(suite)
    assert res["controller_restart"].watchdog_trips >= 2  # hand and master, at once
    assert res["link_cut"].watchdog_trips >= 2  # hand (no command), controller (no state)
    assert dict(res["dup_reorder_storm"].rejects_by_reason)["stale_seq"] > 100
    # a 2 s outage grows the sender's energy total past the per-message cap: a few messages
    # are rejected as jumps, then the epoch is re-baselined (nothing credited) and it resumes
    assert 0 < dict(res["link_cut"].rejects_by_reason).get("energy_jump", 0) <= 4


def test_serial_faults_are_absorbed_by_the_retries(suite: SuiteResult) -> None:
    r = _by_name(suite)["serial_faults"]
    assert r.mode == "realtime" and r.injected > 5  # replies dropped or corrupted
    reasons = dict(r.rejects_by_reason)
    assert reasons.get("serial_no_reply", 0) > 0 and reasons.get("serial_corrupt", 0) > 0
    assert "serial_safe_state" not in reasons  # retried, never latched safe


def test_json_document_totals(suite: SuiteResult) -> None:
    doc = suite.to_json()
    assert doc["faults_run"] == 7 and doc["faults_passed"] == 7 and doc["ok"]
    assert doc["messages_rejected"] == sum(s["rejected"] for s in doc["scenarios"])
    assert doc["energy_violations"] == 0
    json.dumps(doc, allow_nan=False)


@pytest.fixture(scope="module")
def base(cfg: TeleopConfig) -> LockstepResult:
    """The fault-free 4 s run the link-cut and controller-kill tests compare with (made once;
    the kill test reads its first 3.5 s, which are the rows of a 3.5 s run bit for bit:
    ``test_a_shorter_run_is_the_longer_runs_first_rows``)."""
    return run_lockstep(cfg, 4.0, seed=1)


def _link_cut(cfg: TeleopConfig) -> LockstepResult:
    sc = next(s for s in F.scenarios(True) if s.name == "link_cut")
    return run_lockstep(cfg, 4.0, seed=1, hook=F._hook(sc, F._Probe()))


def test_a_shorter_run_is_the_longer_runs_first_rows(cfg: TeleopConfig,
                                                      base: LockstepResult) -> None:
    short = run_lockstep(cfg, 1.5, seed=1)
    n = short.t_s.size
    for name in ("t_s", "hand_setpoint_rad", "displayed_force_n", "master_force_desired_n"):
        assert np.array_equal(getattr(short, name), getattr(base, name)[:n]), name


def test_link_cut_hand_holds_master_force_ramps_out_and_back_without_a_jump(
        cfg: TeleopConfig, base: LockstepResult) -> None:
    r = _link_cut(cfg)
    t = r.t_s
    # before the cut: identical to the baseline
    assert np.array_equal(r.hand_setpoint_rad[t < 1.2], base.hand_setpoint_rad[t < 1.2])
    # no hand state for the timeout: the force sent to the master ramps to zero and stays
    ramp_done = 1.2 + 0.3 + cfg.safety.force_ramp_s
    assert np.all(r.commanded_force_n[(t > ramp_done) & (t < 3.2)] == 0.0)
    assert np.all(np.abs(r.displayed_force_n[(t > ramp_done + 0.05) & (t < 3.2)]) < 0.05)
    assert base.displayed_force_n[(t > 2.0) & (t < 3.2)].min() > 5.0  # it was a real grasp
    # no command for the timeout: the hand holds still
    assert held_still(t, r.hand_setpoint_rad, 1.2 + 0.3, 3.19)
    # the link returns: force and set-point come back ramped, no step larger than the
    # fault-free run ever makes
    after = t[1:] > 3.2
    # no jump: the force returns no faster than the fault-free grasp builds it (with 50 %
    # room: the restarted loop catches up with a grasp that went on while it was down)
    assert np.abs(np.diff(r.displayed_force_n))[after].max() <= \
        1.5 * np.abs(np.diff(base.displayed_force_n)).max()
    assert np.abs(np.diff(r.hand_setpoint_rad, axis=0))[after].max() <= \
        np.abs(np.diff(base.hand_setpoint_rad, axis=0)).max() + 1e-12
    assert recovery_time_s(t, r.hand_setpoint_rad, base.hand_setpoint_rad, 3.2) < 0.5


def test_safe_state_open_opens_the_hand(cfg: TeleopConfig) -> None:

    open_cfg = replace(cfg, safety=replace(cfg.safety, hand_safe_state="open"))
    r = _link_cut(open_cfg)
    t = r.t_s
    # closed on the object before the cut (a first touch is held light for touch_feel_s)
    assert r.hand_setpoint_rad[t < 1.2][-1].min() > 0.3
    assert np.all(r.hand_setpoint_rad[(t > 1.6) & (t < 3.19)] == 0.0)


def test_recovery_time_metric() -> None:
    t = np.arange(0.0, 2.0, 0.01)
    ref = np.zeros((t.size, 3))
    sp = ref.copy()
    sp[(t >= 0.5) & (t < 1.2)] = 0.3
    sp[(t >= 1.3) & (t < 1.32)] = 0.3  # a blip shorter than the settle time resets it
    assert recovery_time_s(t, sp, ref, 0.5, settle_s=0.25) == pytest.approx(0.82, abs=1e-9)
    sp[t >= 1.5] = 0.3  # never settles again
    assert recovery_time_s(t, sp, ref, 0.5, settle_s=0.25) == float("inf")


def test_cli_short_only_flood_json(tmp_path, capsys) -> None:  # noqa: ANN001
    logging.getLogger("teleop.transport").setLevel(logging.ERROR)
    try:
        out = tmp_path / "faults.json"
        rc = main(["faults", "--short", "--only", "malformed_flood", "--json", str(out)])
    finally:
        logging.getLogger("teleop.transport").setLevel(logging.NOTSET)
    assert rc == 0
    doc = json.loads(out.read_text())
    assert doc["faults_run"] == 1 and doc["scenarios"][0]["rejected"] == 2000
    assert "malformed_flood" in capsys.readouterr().out
    assert main(["faults", "--only", "nope"]) == 2


def test_rejections_reach_the_dashboard(tmp_path, cfg: TeleopConfig) -> None:  # noqa: ANN001
    from rerun.chunk import RrdReader

    from teleop.viz.dashboard import open_stream

    sc = F.Scenario("malformed_flood", "", 0.2, 0.4, duration_s=0.6, payloads=200)
    out = tmp_path / "flood.rrd"
    rec = open_stream("faults-test", "save", path=out)
    logging.getLogger("teleop.transport").setLevel(logging.ERROR)
    try:
        run_lockstep(cfg, 0.6, seed=1, hook=F._hook(sc, F._Probe()), rec=rec)
    finally:
        logging.getLogger("teleop.transport").setLevel(logging.NOTSET)
    rec.flush()
    rec.disconnect()
    found = {c.entity_path.lstrip("/") for c in RrdReader(out).stream()
             if not c.is_static and c.num_rows > 0}
    for role in ("hand", "controller"):
        for reason in ("malformed", "out_of_range", "energy_jump", "stale_seq"):
            assert f"rejects/{role}/{reason}" in found


def test_controller_kill_holds_at_once_and_the_restart_resumes_without_a_jump(
        cfg: TeleopConfig, base: LockstepResult) -> None:
    sc = next(s for s in F.scenarios(True) if s.name == "controller_restart")
    r = run_lockstep(cfg, 3.5, seed=1, hook=F._hook(sc, F._Probe()))
    t = r.t_s
    base = _first_rows(base, t.size)  # the fault-free run over the same 3.5 s
    hand_dt = 1.0 / cfg.hand.state_rate_hz
    # liveliness gone: the hand holds from its first tick after the kill (no timeout wait),
    # the grasp force on the trigger goes at once
    assert held_still(t, r.hand_setpoint_rad, 2.0 + hand_dt, 2.5 - 1e-3)
    assert np.all(r.master_force_desired_n[(t > 2.0005) & (t < 2.5)] == 0.0)
    assert base.master_force_desired_n[(t > 2.0005) & (t < 2.5)].min() > 1.0
    # the new controller is heard (no stale drops) and the hand blends back in
    after = t[1:] > 2.5
    assert np.abs(np.diff(r.hand_setpoint_rad, axis=0))[after].max() <= \
        np.abs(np.diff(base.hand_setpoint_rad, axis=0)).max() + 1e-12
    # no jump: the force returns no faster than the fault-free grasp builds it (with 50 %
    # room: the restarted loop catches up with a grasp that went on while it was down)
    assert np.abs(np.diff(r.displayed_force_n))[after].max() <= \
        1.5 * np.abs(np.diff(base.displayed_force_n)).max()
    assert recovery_time_s(t, r.hand_setpoint_rad, base.hand_setpoint_rad, 2.5) < 0.5
    assert r.energy_generated_j == 0.0


def _first_rows(res: LockstepResult, n: int) -> LockstepResult:
    """``res`` with every per-tick series cut to its first ``n`` rows."""
    rows = res.t_s.size
    return replace(res, **{f.name: getattr(res, f.name)[:n] for f in fields(res)
                           if isinstance(getattr(res, f.name), np.ndarray)
                           and getattr(res, f.name).shape[:1] == (rows,)})


def test_passivity_is_judged_by_the_physical_audit(suite: SuiteResult) -> None:
    """Every lockstep scenario carries the physical audit (simulated operator and object) and
    passes it; the ledgers are a second column with their gap to the audit reported."""
    doc = suite.to_json()
    assert doc["audited"] == 6 and doc["audit_violations"] == 0
    for s in doc["scenarios"]:
        if s["mode"] != "lockstep":
            assert s["passive_audit"] is None and s["audit"].startswith("none")
            continue
        assert s["passive_audit"] is True and s["audit_violations"] == 0, s["name"]
        assert s["audit"].startswith("physical")
        assert s["min_audit_margin_j"] >= 0.0
        assert s["audit_energy_generated_j"] == 0.0
        assert set(s["ledger_audit_gap_j"]) == {"operator", "environment"}
        assert all(np.isfinite(v) for v in s["ledger_audit_gap_j"].values())
        assert s["ledger_energy_violations"] == s["energy_violations"] == 0


def test_a_physical_violation_fails_the_scenario(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A hand that skips its set-point modulation (the servo-spring layer, ``hand_port =
    servo``, 0.1 J tanks): the physical audit shows the ports received more than the tanks
    held + what was taken, and the scenario fails on it."""
    from teleop.control.passivity_layer import spring_energy_j

    def project(desired, previous, x, budget, k, tau=float("inf")):  # type: ignore[no-untyped-def]
        return desired, spring_energy_j(desired, x, k, tau) - spring_energy_j(previous, x,
                                                                             k, tau), False

    patch_sides(monkeypatch, "pspm_project", project)
    small = load_config(None, [*BASE_OVERRIDES, "controller.tank.initial_j=0.1",
                               "controller.tank.reserve_j=0.0",
                               "controller.ports.hand_port=servo"])
    sc = next(s for s in F.scenarios(True) if s.name == "link_cut")
    base = run_lockstep(small, sc.duration_s, seed=1, hand=F._guard(small))
    r = F.run_scenario(small, sc, base)
    assert r.has_audit and r.audit_violations > 0 and not r.ok
    assert any(f.startswith("physical energy audit") for f in r.failures)
    assert r.to_json()["passive_audit"] is False


def test_live_results_say_they_have_no_audit(cfg: TeleopConfig) -> None:
    from services import faults_live

    r = faults_live._judge("controller_restart", "kill", cfg, {}, {}, 1.0, 2.0, 0, {}, [],
                           "", 0.0)
    doc = r.to_json()
    assert not r.has_audit and doc["passive_audit"] is None
    assert doc["audit_violations"] is None and "live mode" in doc["audit"]
