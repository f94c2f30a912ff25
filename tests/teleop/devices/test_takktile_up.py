"""`teleop up --set hand.backend=reflex-takktile` against `teleop hand-emulator`: real UDP
sockets on loopback, real zenoh sessions, the three services as processes."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from services.bench import free_port
from sim.hand_emulator_bench import start_board_process, stop_board_process
from teleop.recording import read_recording


def up(tmp_path: Path, board_port: int, seconds: float) -> tuple[subprocess.CompletedProcess[str],
                                                                  Path]:
    port = free_port()
    rec = tmp_path / "rec"
    proc = subprocess.run(
        [sys.executable, "-m", "teleop.cli", "up", "--duration", str(seconds), "--dashboard",
         "off", "--record", str(rec), "--set", f"zenoh.endpoint=tcp/127.0.0.1:{port}",
         "--set", f"session.name=tt{port}", "--set", "hand.backend=reflex-takktile",
         "--set", "hand.takktile.network=unicast", "--set", "hand.takktile.address=127.0.0.1",
         "--set", f"hand.takktile.port={board_port}"],
        capture_output=True, text=True, timeout=180)
    return proc, rec


@pytest.mark.network
@pytest.mark.slow
def test_a_grasp_on_the_emulated_takktile_is_felt_by_the_operator(tmp_path: Path) -> None:
    """Grasps felt as force; then the board falls silent (7 s after the hand's first packet to
    it) and the hand holds; the operator feels no grasp force, only the passivity layer's
    damping."""
    board, board_port = start_board_process(("--silent-after", "7"))  # a cylinder in the way
    try:
        proc, rec = up(tmp_path, board_port, 10.0)
        assert board.poll() is None  # the emulator survived the run
    finally:
        status = stop_board_process(board)
    assert status == 0  # and stopped cleanly on SIGTERM
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "hand exited" not in proc.stdout + proc.stderr
    hand = read_recording(rec / "hand.csv")
    ctrl = read_recording(rec / "controller.csv")
    master = read_recording(rec / "master.csv")
    press = np.max([hand.column(f"pressure_f{f}_{i}") for f in (1, 2, 3) for i in range(9)],
                   axis=0)
    assert np.abs(press[:5]).max() < 15  # fingers open at start: resting offsets removed
    # the cells see every contact: the unseen-contact guard stays quiet on this backend too
    assert hand.column("unseen_contact").max() == 0.0
    assert press.max() > 100  # the grasp presses the tactile sensors (model outputs)
    # the pressures travel to the controller over zenoh ...
    seen = np.max([ctrl.column(f"max_pressure_f{f}") for f in (1, 2, 3)], axis=0)
    assert seen.max() > 100
    # ... and the operator feels them: force while pressed, none while free
    # (ticks where a watchdog ramped the force down are left out: on a loaded host a
    # scheduling stall of the emulator reads as a silent board, which is the point of it)
    felt = np.interp(ctrl.t_s, master.t_s, master.column("displayed_force_n"))
    live = ctrl.column("watchdog") == 0
    pressed, free = (seen > 100) & live, (seen < 5) & live
    assert pressed.sum() > 100 and free.sum() > 100  # controller ticks (1 kHz)
    assert np.percentile(felt[pressed], 75) > 1.0
    assert np.median(np.abs(felt[free])) < 0.2
    # the silent board: the hand's watchdog holds to the end, the operator feels nothing
    end = hand.t_s > hand.t_s[-1] - 1.0
    assert np.all(hand.column("watchdog")[end] == 1.0)
    assert "brain board silent" in proc.stdout + proc.stderr
    quiet = master.t_s > master.t_s[-1] - 0.5
    assert np.all(master.column("force_command_n")[quiet] == 0.0)  # nothing from the hand
    assert np.all(master.column("model_force_n")[quiet] == 0.0)  # nor the local model
    # what remains is the tank controller's damping, at the velocity the passivity layer
    # measured: the position step over the time since the last tick (across a stall, when the
    # loop dropped deadlines, this mean velocity differs from the device's reading at the tick)
    q, t = master.column("trigger_position_m"), master.t_s
    v_layer = np.diff(q, prepend=q[0]) / np.maximum(np.diff(t, prepend=t[0] - 1e-3), 1e-3)
    damping = master.column("tlc_damping_n_s_per_m") * np.abs(v_layer)
    assert np.all(np.abs(master.column("displayed_force_n")[quiet]) <= damping[quiet] + 0.01)
    print(f"felt while pressed: median {np.median(felt[pressed]):.2f} N; hand watchdog ticks "
          f"{int(hand.column('watchdog').sum())} of {len(hand)}")
