"""The physical energy audit read from a recorded run (``teleop.analysis.port_audit``), on
recordings built here with known answers: the master's 1 kHz operator port and the hand's
40 Hz object port, each side's initial energy from its ledger identity.  The live runs are
audited in tests/test_sweep_live.py and tests/test_sweep_live_grasps.py."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from teleop.analysis.port_audit import audit_margin_j, recorded_audit
from teleop.cli import main
from teleop.recording import Recording, read_recording, write_recording

INITIAL_J = 1.0  # each of master, hand, controller


def _run(d: Path, *, object_j: float = 2.5, energy_scale: float | None = None,
         controller_start_s: float = 3.0, audit_on_hand: bool = True) -> Path:
    """A 10 s run: the operator puts 2 J in through the trigger (ramped), the fingers deliver
    ``object_j`` to the object by 8 s, the object pushes 0.2 J back.  Initial energy 1 J on
    each side (master, hand, controller from ``controller_start_s``), so the bound is
    3 + 2 + 0.2 = 5.2 J."""
    t = 3.0 + np.arange(0.0, 10.0, 0.001)
    ramp = np.clip((t - 4.0) / 4.0, 0.0, 1.0)
    taken_m = 2.0 * ramp
    master = {"t_s": t, "trigger_position_m": 0.01 * ramp, "displayed_force_n": 2.0 * ramp,
              "tank_j": INITIAL_J + taken_m, "port_in_j": taken_m, "port_out_j": 0.0 * t,
              "sent_j": 0.0 * t, "received_j": 0.0 * t, "dissipated_j": 0.0 * t,
              "audit_delivered_j": 0.0 * t, "audit_taken_j": taken_m}
    meta: tuple[tuple[str, str], ...] = (("role", "master"), ("grasp_threshold_m", "0.0025"))
    if energy_scale is not None:
        meta += (("energy_scale", f"{energy_scale:g}"),)
    write_recording(d / "master.csv", Recording.from_columns(master, meta))
    th = 3.0 + np.arange(0.0, 10.0, 0.025)
    rh = np.clip((th - 4.0) / 4.0, 0.0, 1.0)
    hand: dict[str, np.ndarray] = {"t_s": th, "tank_j": np.full_like(th, INITIAL_J)}
    for i in range(27):
        hand[f"pressure_f{i // 9 + 1}_{i % 9}"] = 0.0 * th
    for f in (1, 2, 3):
        hand[f"proximal_angle_rad_f{f}"] = hand[f"distal_angle_rad_f{f}"] = 0.0 * th
    if audit_on_hand:
        hand["audit_delivered_j"] = object_j * rh
        hand["audit_taken_j"] = 0.2 * rh
    write_recording(d / "hand.csv", Recording.from_columns(hand, (("role", "hand"),)))
    tc = t[t >= controller_start_s]
    write_recording(d / "controller.csv", Recording.from_columns(
        {"t_s": tc, "store_j": np.full_like(tc, INITIAL_J)}, (("role", "controller"),)))
    return d


def _audit(d: Path, energy_scale: float = 1.0):  # noqa: ANN202
    return recorded_audit(*(read_recording(d / f"{r}.csv") for r in
                            ("master", "hand", "controller")), energy_scale)


def test_the_margin_is_initial_plus_taken_minus_delivered_with_the_operator_scaled() -> None:
    m = audit_margin_j(3.0, 2.0, [0.0, 1.0], [0.0, 0.5], [0.0, 0.25], [0.0, 4.0])
    assert m.tolist() == [3.0, 3.0 + 2.0 * 0.5 + 0.25 - 4.0]


def test_a_passive_run_reads_its_margin_from_both_ports(tmp_path: Path) -> None:
    a = _audit(_run(tmp_path))
    assert a is not None and a.passive
    assert a.initial_j == pytest.approx(3.0)
    assert a.min_margin_j == pytest.approx(5.2 - 2.5, abs=2e-3)
    assert a.min_at_s == pytest.approx(8.0, abs=0.03)  # reached when the ramps end
    assert (a.operator_taken_j, a.operator_delivered_j) == pytest.approx((2.0, 0.0))
    assert (a.environment_delivered_j, a.environment_taken_j) == pytest.approx((2.5, 0.2))
    # the books: the master's ledger took what the physics says (gap 0); the hand's ledger has
    # no port accounts here, so its gap is unknown
    assert a.ledger_gap_operator_j == pytest.approx(0.0, abs=1e-9)
    assert np.isnan(a.ledger_gap_environment_j)


def test_energy_created_at_the_object_is_found_when_and_by_how_much(tmp_path: Path) -> None:
    a = _audit(_run(tmp_path, object_j=6.0))  # 0.8 J more than the bound 5.2 J
    assert a is not None and not a.passive
    assert a.generated_j == pytest.approx(0.8, abs=2e-3)
    assert a.min_at_s == pytest.approx(8.0, abs=0.03)  # where the ramps end


def test_the_power_scale_weights_the_operator_port(tmp_path: Path) -> None:
    """With rho = 2 the master's 1 J initial and 2 J taken count double (hand-side joules):
    bound 2 + 1 + 1 + 4 + 0.2 = 8.2 J, so 6 J to the object is passive; read as plain
    joules (the scale ignored) it is not."""
    d = _run(tmp_path, object_j=6.0, energy_scale=2.0)
    a = _audit(d, 2.0)
    assert a is not None and a.passive and a.min_margin_j == pytest.approx(2.2, abs=2e-3)
    assert not _audit(d, 1.0).passive  # type: ignore[union-attr]
    assert main(["grasps", str(d), "--json", str(d / "g.json")]) == 0  # the scale on record
    assert json.loads((d / "g.json").read_text())["energy_audit"]["energy_scale"] == 2.0


def test_the_controllers_energy_counts_only_once_it_runs(tmp_path: Path) -> None:
    """Energy delivered before the controller starts may not borrow its store: 4.5 J to the
    object by 8 s is within master + hand + controller + taken (5.2 J), but a controller that
    starts at 9 s leaves 4.2 J to pay it from 8 s to 9 s."""
    early = _audit(_run(tmp_path, object_j=4.5, controller_start_s=3.0))
    assert early is not None and early.passive
    assert early.min_margin_j == pytest.approx(0.7, abs=2e-3)
    (tmp_path / "late").mkdir()
    late = _audit(_run(tmp_path / "late", object_j=4.5, controller_start_s=9.0))
    assert late is not None and not late.passive
    assert late.generated_j == pytest.approx(0.3, abs=2e-3) and 7.9 < late.min_at_s < 9.0


def test_teleop_grasps_prints_the_audit_and_fails_on_energy_created(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    ok = _run(tmp_path)
    assert main(["grasps", str(ok)]) == 0
    out = capsys.readouterr().out
    assert "physical energy audit (simulated operator and object): passive" in out
    (tmp_path / "bad").mkdir()
    bad = _run(tmp_path / "bad", object_j=6.0)
    assert main(["grasps", str(bad), "--json", str(tmp_path / "bad.json")]) == 1
    out = capsys.readouterr().out
    assert "ENERGY CREATED: 0.80" in out and "FAIL: the physics shows energy created" in out
    doc = json.loads((tmp_path / "bad.json").read_text())["energy_audit"]
    assert doc["audited"] and not doc["passive"] and doc["generated_j"] == pytest.approx(0.8,
                                                                                          abs=2e-3)


def test_without_a_simulated_port_there_is_no_audit(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    d = _run(tmp_path, audit_on_hand=False)  # e.g. the dynamixel driver or a real hand
    assert _audit(d) is None
    assert main(["grasps", str(d), "--json", str(tmp_path / "g.json")]) == 0
    assert "physical energy audit: none" in capsys.readouterr().out
    assert json.loads((tmp_path / "g.json").read_text())["energy_audit"] == {"audited": False}
