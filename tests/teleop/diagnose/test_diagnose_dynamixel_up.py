"""End to end: a physical effect in the emulated servos' physics, `teleop up` on the dynamixel
backend records the hand, `teleop diagnose --model finger --finger 1` names the effect.

Real parts throughout: `teleop servo-emulator` (a pty, the finger model behind real MX-28
packets) in its own process, `teleop up` (three services, real zenoh on 127.0.0.1, the dynamixel
backend over dynamixel-sdk), the recording read back from disk, the diagnosis on the command
line.  The effect is a 0.2 s dead time in the emulated fingers; a second run without it is the
control (what the dynamixel path alone looks like to the finger model).
"""

from __future__ import annotations

import json
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sim.servo_emulator_bench import start_emulator_process, stop_emulator_process
from teleop.recording import read_recording

DEAD_TIME_S = 0.2
UP_S = 20
SKIP_S = 3.0  # start-up: the first hand ticks may stall while the services meet
# a bus retry stalls a hand tick (0.1 s timeout x 3 attempts per servo) on a loaded machine:
# --split-gaps restarts the simulation after such a gap instead of refusing the recording


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _ticks(csv: Path) -> tuple[int, int]:
    """(hand rows recorded after the skipped start, rows a 40 Hz hand would have)."""
    t = read_recording(csv).t_s
    return int(np.sum(t >= t[0] + SKIP_S)), int((t[-1] - t[0] - SKIP_S) * 40)


def _record(tmp: Path, name: str, effect: tuple[str, ...]) -> Path:
    """One recording; a second try when the hand stalled on more than 40 % of its ticks (bus
    retries on a machine too loaded to serve the pty in time), said in the failure."""
    got: list[tuple[int, int]] = []
    for attempt in range(2):
        csv = _record_once(tmp, f"{name}{attempt}", effect)
        got.append(_ticks(csv))
        if got[-1][0] >= 0.6 * got[-1][1]:
            return csv
    raise AssertionError(f"the hand stalled: (rows, 40 Hz ticks) per attempt {got}")


def _record_once(tmp: Path, name: str, effect: tuple[str, ...]) -> Path:
    emu, path = start_emulator_process(1, ("--set", "hand.sim.object.kind=none", *effect))
    try:
        port = _free_port()
        rec = tmp / name
        proc = subprocess.run(
            [sys.executable, "-m", "teleop.cli", "up", "--duration", str(UP_S), "--dashboard",
             "off", "--record", str(rec), "--set", f"zenoh.endpoint=tcp/127.0.0.1:{port}",
             "--set", f"session.name=dg{port}", "--set", "hand.backend=dynamixel",
             "--set", f"hand.dynamixel.port={path}", "--set", "hand.dynamixel.timeout_s=0.1",
             "--set", "hand.sim.object.kind=none"],
            capture_output=True, text=True, timeout=180)
        assert emu.poll() is None  # the emulator survived the run
    finally:
        stop_emulator_process(emu)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return rec / "hand.csv"


def _diagnose_each(*csvs: Path) -> list[dict]:
    """The JSON reports of ``teleop diagnose`` on each recording, the diagnoses run at once
    (CPU-bound, and nothing else runs beside a real-time test: one core each)."""
    procs = [subprocess.Popen(
        [sys.executable, "-m", "teleop.cli", "diagnose", str(csv), "--model", "finger",
         "--finger", "1", "--skip", str(SKIP_S), "--split-gaps", "--json", "-"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for csv in csvs]
    docs = []
    try:
        for proc in procs:
            out, err = proc.communicate(timeout=600)
            assert proc.returncode == 0, err[-2000:]
            docs.append(json.loads(out))
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    return docs


def delay_named(doc: dict) -> str:
    """What the report says about a recording with a dead time in the servos: "" when it names
    the delay (``dead_time`` first, or ``actuator_lag`` first with the note that the two
    cannot be told apart on this recording, naming both and the separating experiment);
    otherwise why not."""
    names = [e["name"] for e in doc["effects"]]
    if not names:
        return f"nothing named (ranking {doc['ranking']})"
    if names[0] == "dead_time":
        return ""
    notes = [a for a in doc.get("ambiguous", []) if "dead_time" in a and "actuator_lag" in a
             and "to separate them" in a]
    if names[0] == "actuator_lag" and notes:
        return ""
    return f"named {names} with notes {doc.get('ambiguous')}"


def test_the_judgement_refuses_an_unrelated_effect_or_a_lag_without_the_note() -> None:
    lag = {"name": "actuator_lag", "params": {"actuator_lag": 0.15}}
    note = ("cannot tell actuator_lag from dead_time on this recording (...); to separate "
            "them: a fast step")
    assert delay_named({"effects": [{"name": "dead_time"}], "ranking": []}) == ""
    assert delay_named({"effects": [lag], "ranking": [], "ambiguous": [note]}) == ""
    assert delay_named({"effects": [lag], "ranking": [], "ambiguous": []}) != ""
    assert delay_named({"effects": [{"name": "coulomb_friction"}], "ranking": [],
                        "ambiguous": [note.replace("actuator_lag", "coulomb_friction")]}) != ""
    assert delay_named({"effects": [], "ranking": []}) != ""


@pytest.mark.network
@pytest.mark.slow
def test_a_dead_time_in_the_emulated_servos_is_named_from_the_up_recording(
        tmp_path: Path) -> None:
    csv = _record(tmp_path, "delay", ("--effect", f"dead_time={DEAD_TIME_S}"))
    assert "hand_backend: dynamixel" in csv.read_text()[:2000]  # the driver is on record
    doc, clean = _diagnose_each(csv, _record(tmp_path, "clean", ()))
    why = delay_named(doc)
    assert not why, why
    first = doc["effects"][0]
    found = first["params"][first["name"]]
    # dead time measured 0.117-0.193 s for 0.2 s, an actuator lag standing in for it 0.147 s,
    # while a restart (the driver's load-estimated contacts, bus-retry gaps) settled from
    # rest; 0.214 s since it starts at the measured angle and load
    assert 0.4 * DEAD_TIME_S < found < 1.5 * DEAD_TIME_S, first
    assert first["holdout_gain"] > 0.3
    # RSS down by more than a quarter (NRMSE x 0.85), as the held-out gain above; measured
    # NRMSE x 0.65-0.84 (x 0.84: actuator_lag first, with the note)
    assert doc["fit"]["after"]["nrmse"] < 0.85 * doc["fit"]["before"]["nrmse"]
    # the emulator has no sensor offset: one named stands in for the error of the segments
    # restarted after a gap or a flagged stretch (it was named at its 0.5 rad bound on every
    # run while a restart settled the finger from rest and stopped short of the measured
    # angle; now it starts there, at the measured load: tests/sim/test_finger_hand_clock.py)
    assert "sensor_offset" not in named_effects(doc), doc["effects"]

    named = named_effects(clean)
    # the dynamixel path has no such delay, nor a lag that could stand in for one
    assert named.get("dead_time", 0.0) < 0.25 * DEAD_TIME_S, clean["effects"]
    assert named.get("actuator_lag", 0.0) < 0.25 * DEAD_TIME_S, clean["effects"]
    assert "sensor_offset" not in named, clean["effects"]


def named_effects(doc: dict) -> dict[str, float]:
    """The effects a report names, by name (their values)."""
    return {e["name"]: e["params"][e["name"]] for e in doc["effects"]}
