"""``teleop grasps DIR``: a recorded run judged grasp by grasp, on recordings built here with
known answers (a weak third grasp, an empty master tank while squeezing and another while the
trigger is open, a watchdog trip, a stalled master); the live run is judged in
tests/test_sweep_live_grasps.py."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from teleop.analysis.recorded_run import judge_recorded_run, read_run_dir
from teleop.cli import main
from teleop.recording import Recording, write_recording

THRESHOLD_M = 0.0025
#: grasp k: trigger closed over [5k + 1, 5k + 3) s; the hand's peak pressure then
PEAKS = (600.0, 610.0, 300.0, 605.0)


def _write_run(d: Path, *, master_meta: tuple[tuple[str, str], ...] | None = None,
               drop: str | None = None, master_gap: tuple[float, float] | None = None,
               hand_gap: tuple[float, float] | None = None,
               peaks: tuple[float, ...] = PEAKS,
               commands: tuple[float, ...] | None = None) -> None:
    span_s = 5.0 * len(peaks)  # one grasp every 5 s
    t = np.arange(0.0, span_s, 0.01) + 3.0  # services start after the launcher's epoch
    if master_gap is not None:  # the master's process stalled: no rows in (a, b)
        t = t[(t <= master_gap[0]) | (t >= master_gap[1])]
    phase = (t - 3.0) % 5.0
    closed = (phase >= 1.0) & (phase < 3.0)
    k = ((t - 3.0) // 5.0).astype(int)
    tank = np.ones_like(t)
    tank[(t >= 14.0) & (t < 14.5)] = 0.0  # grasp 2, trigger closed: counts
    tank[(t >= 17.0) & (t < 17.5)] = 0.0  # trigger open: does not count
    master = {"t_s": t, "trigger_position_m": np.where(closed, 0.012, 0.0),
              "displayed_force_n": np.where(closed, 8.0, 0.0), "tank_j": tank,
              "watchdog": np.zeros_like(t)}
    if commands is not None:  # the controller's measured-force command, per grasp
        master["force_command_n"] = np.where(closed, np.array(commands)[np.clip(k, 0, len(commands) - 1)],
                                             0.0)
    if drop:
        master.pop(drop)
    meta = (("role", "master"), ("grasp_threshold_m", f"{THRESHOLD_M:g}")) \
        if master_meta is None else master_meta
    write_recording(d / "master.csv", Recording.from_columns(master, meta))

    th = np.arange(0.0, span_s, 0.025) + 3.0
    if hand_gap is not None:  # the hand's process stalled: no rows in (a, b)
        th = th[(th <= hand_gap[0]) | (th >= hand_gap[1])]
    ph = (th - 3.0) % 5.0
    kh = ((th - 3.0) // 5.0).astype(int)
    holding = (ph >= 1.5) & (ph < 3.0)
    hand: dict[str, np.ndarray] = {"t_s": th}
    for i in range(27):
        hand[f"pressure_f{i // 9 + 1}_{i % 9}"] = np.where(
            holding & (i == 4), np.array(peaks)[np.clip(kh, 0, len(peaks) - 1)], 0.0)
    for f in (1, 2, 3):
        hand[f"proximal_angle_rad_f{f}"] = np.where(holding, 0.5, 0.0)
        hand[f"distal_angle_rad_f{f}"] = np.where(holding, 0.4, 0.0)
    hand["tank_j"] = np.full_like(th, 9.0)
    hand["watchdog"] = ((th >= 8.0) & (th < 8.2)).astype(float)
    hand["limited"] = ((th >= 9.0) & (th < 10.5)).astype(float)
    write_recording(d / "hand.csv", Recording.from_columns(hand, (("role", "hand"),)))
    del k


@pytest.fixture()
def run_dir(tmp_path: Path) -> Path:
    _write_run(tmp_path)
    return tmp_path


def test_every_grasp_against_the_first(run_dir: Path) -> None:
    r = judge_recorded_run(read_run_dir(run_dir), THRESHOLD_M)
    assert len(r.grasps.grasps) == 4
    ratios = [g.pressure_ratio for g in r.grasps.grasps]
    np.testing.assert_allclose(ratios, np.array(PEAKS) / PEAKS[0])
    assert r.grasps.min_pressure_ratio == pytest.approx(0.5)
    assert r.grasps.min_closure_ratio == pytest.approx(1.0)  # curl 0.9 rad each time


def test_an_empty_tank_counts_only_while_the_trigger_is_closed(run_dir: Path) -> None:
    r = judge_recorded_run(read_run_dir(run_dir), THRESHOLD_M)
    master = next(e for e in r.empty if e.store == "master tank")
    assert master.spells == 1
    assert master.empty_s == pytest.approx(0.5, abs=0.011)  # not the 0.5 s while open
    assert master.longest_at_s == pytest.approx(14.0, abs=0.011)
    assert master.closed_s == pytest.approx(8.0, abs=0.05)  # four 2 s squeezes
    assert master.min_j == 0.0
    hand = next(e for e in r.empty if e.store == "hand tank")
    assert hand.spells == 0 and hand.min_j == 9.0
    assert [e.store for e in r.empty] == ["master tank", "hand tank"]  # no controller.csv


def test_guard_time_is_measured(run_dir: Path) -> None:
    r = judge_recorded_run(read_run_dir(run_dir), THRESHOLD_M)
    g = {x.what: x for x in r.guards}
    assert g["hand command watchdog"].active_s == pytest.approx(0.2, abs=0.03)
    assert g["hand command watchdog"].first_at_s == pytest.approx(8.0)
    assert g["hand command watchdog"].spells == 1
    assert g["master force-command watchdog"].active_s == 0.0
    # the hand's layer holding a set-point back: its tank at its floor (0.01 J) reads above
    # the 5 mJ empty line, so the report says so here (a dynamixel run: 70 % of the time)
    assert g["hand set-point held back by its tank"].active_s == pytest.approx(1.5, abs=0.03)
    assert g["hand set-point held back by its tank"].first_at_s == pytest.approx(9.0)


def test_a_grasp_felt_in_full_but_not_held_is_named(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """The displayed force is 8 N in every grasp; a third grasp at a third of the first's
    pressure is felt, not held (named in the report and the JSON); at half (the fixture's
    PEAKS) it is only weak."""
    _write_run(tmp_path, peaks=(600.0, 610.0, 200.0, 605.0))
    r = judge_recorded_run(read_run_dir(tmp_path), THRESHOLD_M)
    assert [g.index for g in r.judged.felt_not_held] == [2]
    assert main(["grasps", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "felt, not held: 1 grasps (grasp 2)" in out
    assert main(["grasps", str(tmp_path), "--json", "-"]) == 0
    assert json.loads(capsys.readouterr().out)["felt_not_held"] == [2]
    weak = tmp_path / "weak"
    weak.mkdir()
    _write_run(weak)  # the third grasp at 0.50 of the first: weak, still held
    assert judge_recorded_run(read_run_dir(weak), THRESHOLD_M).judged.felt_not_held == ()
    assert main(["grasps", str(weak)]) == 0
    assert "felt, not held" not in capsys.readouterr().out


def test_a_weak_grip_that_still_asks_for_the_full_display_is_felt_as_held(
        tmp_path: Path) -> None:
    """With the measured-force command recorded: the third grasp at a third of the first's
    pressure whose pressure still asked for the 8 N shown (the display saturates) is not
    named; the same grasp asking for 2 N is."""
    held = tmp_path / "held"
    held.mkdir()
    _write_run(held, peaks=(600.0, 610.0, 200.0, 605.0), commands=(8.0, 8.0, 8.0, 8.0))
    assert judge_recorded_run(read_run_dir(held), THRESHOLD_M).judged.felt_not_held == ()
    ghost = tmp_path / "ghost"
    ghost.mkdir()
    _write_run(ghost, peaks=(600.0, 610.0, 200.0, 605.0), commands=(8.0, 8.0, 2.0, 8.0))
    r = judge_recorded_run(read_run_dir(ghost), THRESHOLD_M)
    assert [g.index for g in r.judged.felt_not_held] == [2]
    assert r.judged.grasps[2].measured_force_n == 2.0


def test_cli_floor_and_json(run_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["grasps", str(run_dir)]) == 0
    out = capsys.readouterr().out
    assert "4 complete grasps" in out and "0.50" in out
    assert main(["grasps", str(run_dir), "--floor", "0.9"]) == 1  # the weak third grasp
    assert "FAIL: 1 grasps below 0.9" in capsys.readouterr().out
    assert main(["grasps", str(run_dir), "--floor", "0.4"]) == 0
    assert main(["grasps", str(run_dir), "--floor", "0.4", "--max-empty-s", "0.2"]) == 1
    capsys.readouterr()
    assert main(["grasps", str(run_dir), "--json", "-"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["grasp_count"] == 4 and d["min_pressure_ratio"] == pytest.approx(0.5)
    assert d["grasp_threshold_m"] == THRESHOLD_M
    assert d["after_first"] is None  # four grasps: too few to set the first against three


def test_the_first_against_the_next_three_in_the_report(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """An overshooting first grasp: 0.83 over the first, the later ones hold (1.00)."""
    _write_run(tmp_path, peaks=(720.0, 600.0, 590.0, 600.0, 600.0, 598.0))
    assert main(["grasps", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert ("after the first (peak pressure): the best of the next 3 0.83 of the first; "
            "the weakest later grasp (grasp 5) 1.00 of that best") in out
    assert main(["grasps", str(tmp_path), "--json", "-"]) == 0
    a = json.loads(capsys.readouterr().out)["after_first"]
    assert a["early_best_over_first"] == pytest.approx(600 / 720, rel=0.02)
    assert a["later_weakest_grasp"] == 5


def test_a_grasp_a_recording_gap_interrupts_is_listed_not_judged(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A stalled master (its rows stop for 0.6 s inside the weak third grasp, closed over
    [14, 16) s) makes that grasp unjudgeable: listed with the gap, left out of the weakest and
    of ``--floor``; a 0.1 s stall interrupts nothing."""
    _write_run(tmp_path, master_gap=(14.5, 15.1))
    r = judge_recorded_run(read_run_dir(tmp_path), THRESHOLD_M)
    assert len(r.grasps.grasps) == 4 and [x.role for x in r.gaps] == ["master"]
    assert r.gaps[0].gap_s == pytest.approx(0.6, abs=0.011)
    assert [r.interrupted(k) for k in range(4)] == [False, False, True, False]
    assert [g.index for g in r.judged.grasps] == [0, 1, 3]
    assert r.judged.min_pressure_ratio == pytest.approx(1.0)
    assert main(["grasps", str(tmp_path), "--floor", "0.9"]) == 0
    out = capsys.readouterr().out
    assert "1 interrupted by a recording gap" in out and "master" in out
    assert [ln for ln in out.splitlines() if ln.endswith("  gap")][0].split()[0] == "2"
    assert main(["grasps", str(tmp_path), "--json", "-"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert [g["interrupted"] for g in d["grasps"]] == [False, False, True, False]
    assert d["judged_count"] == 3 and d["gaps"][0]["role"] == "master"
    short = tmp_path / "short"
    short.mkdir()
    _write_run(short, master_gap=(14.5, 14.6))
    r = judge_recorded_run(read_run_dir(short), THRESHOLD_M)
    assert not r.gaps and r.judged.min_pressure_ratio == pytest.approx(0.5)


def test_a_store_empty_while_the_hand_stalled_is_reported_apart(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The hand silent over (13.8, 14.3) s: the master tank's 0.5 s empty spell from 14.0 s
    (trigger closed) lies within the gap and the 0.5 s after it: reported apart, not
    counted; the same spell without the gap counts (test above)."""
    _write_run(tmp_path, hand_gap=(13.8, 14.3))
    r = judge_recorded_run(read_run_dir(tmp_path), THRESHOLD_M)
    assert [x.role for x in r.gaps] == ["hand"]
    master = next(e for e in r.empty if e.store == "master tank")
    assert master.spells == 0 and master.empty_s == 0.0
    assert master.excused_s == pytest.approx(0.5, abs=0.011)
    assert main(["grasps", str(tmp_path), "--floor", "0.4", "--max-empty-s", "0.2"]) == 0
    assert "0.50 s more during recording gaps, not counted" in capsys.readouterr().out


def test_an_interrupted_first_grasp_hands_the_reference_on(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Grasp 0 (closed over [4, 6) s) interrupted: the ratios are over grasp 1 (peak 610)."""
    _write_run(tmp_path, master_gap=(4.5, 5.5))
    r = judge_recorded_run(read_run_dir(tmp_path), THRESHOLD_M)
    assert [g.index for g in r.judged.grasps] == [1, 2, 3]
    np.testing.assert_allclose([g.pressure_ratio for g in r.judged.grasps],
                               np.array(PEAKS[1:]) / PEAKS[1])
    assert main(["grasps", str(tmp_path), "--floor", "0.9"]) == 1  # the weak third grasp
    out = capsys.readouterr().out
    assert "weakest over grasp 1:" in out
    assert "FAIL: 1 grasps below 0.9 of grasp 1 (the first without a recording gap) [2]" in out


def test_threshold_from_the_recording_or_the_option(run_dir: Path) -> None:
    # a threshold above the squeeze finds no grasp at all
    r = judge_recorded_run(read_run_dir(run_dir), 0.02)
    assert not r.grasps.grasps
    assert main(["grasps", str(run_dir), "--threshold-m", "0.02", "--floor", "0.9"]) == 1


@pytest.mark.parametrize(("kwargs", "needle"), [
    ({"drop": "trigger_position_m"}, "no column 'trigger_position_m'"),
    ({"master_meta": (("grasp_threshold_m", "wide"),)}, "grasp_threshold_m 'wide'"),
])
def test_bad_recordings_are_one_line_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                            kwargs: dict[str, object], needle: str) -> None:
    _write_run(tmp_path, **kwargs)  # type: ignore[arg-type]
    assert main(["grasps", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and "master.csv" in err and len(err.splitlines()) == 1


def test_missing_files_are_one_line_exit_2(tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["grasps", str(tmp_path / "nowhere")]) == 2
    assert "no such directory" in capsys.readouterr().err
    _write_run(tmp_path)
    (tmp_path / "hand.csv").unlink()
    assert main(["grasps", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "hand.csv: missing" in err and len(err.strip().splitlines()) == 1
    assert main(["grasps", str(tmp_path), "--every", "0"]) == 2
