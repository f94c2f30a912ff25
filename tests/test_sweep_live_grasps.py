"""Live endurance check: ``teleop up`` for 90 s (three processes over zenoh on loopback),
every grasp of the virtual operator's repeated script judged like the lockstep endurance
(:func:`teleop.analysis.sweep_endurance.grasps_from_columns`)."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from teleop.analysis.grasps import GraspSeries, format_grasps
from teleop.analysis.sweep_endurance import grasps_from_columns
from teleop.config import load_config
from teleop.recording import Recording, read_recording

pytestmark = [pytest.mark.network, pytest.mark.slow]

DURATION_S = 90.0


def _held(src: Recording, t: np.ndarray, name: str) -> np.ndarray:
    idx = np.clip(np.searchsorted(src.t_s, t, side="right") - 1, 0, len(src.t_s) - 1)
    return src.column(name)[idx].astype(float)


def grasps_from_recordings(master: Recording, hand: Recording) -> GraspSeries:
    """Every grasp of a ``teleop up --record`` run (hand held on the master's clock)."""
    t = master.t_s
    pressure = np.column_stack([_held(hand, t, f"pressure_f{i // 9 + 1}_{i % 9}")
                                for i in range(27)])
    prox = np.column_stack([_held(hand, t, f"proximal_angle_rad_f{i}") for i in (1, 2, 3)])
    dist = np.column_stack([_held(hand, t, f"distal_angle_rad_f{i}") for i in (1, 2, 3)])
    return grasps_from_columns(t, master.column("trigger_position_m"), pressure, prox, dist,
                               master.column("displayed_force_n"), load_config())


@pytest.fixture(scope="module")
def grasps(tmp_path_factory: pytest.TempPathFactory) -> GraspSeries:
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
    g = grasps_from_recordings(read_recording(Path(rec) / "master.csv"),
                               read_recording(Path(rec) / "hand.csv"))
    print(format_grasps(g))
    return g


def test_every_grasp_of_the_live_run_is_found(grasps: GraspSeries) -> None:
    assert len(grasps.grasps) >= int(DURATION_S / 4.5) - 2  # a grasp every 4.5 s
    assert grasps.grasps[0].peak_pressure > 100  # the first grasp closed on the object


def test_every_live_grasp_holds_up_against_the_first(grasps: GraspSeries) -> None:
    """The loop must keep working: every grasp reaches 90 % of the first's peak pressure,
    closure and felt force (issue 13's floor)."""
    bad = [(g.index, round(g.pressure_ratio, 3), round(g.felt_ratio, 3))
           for g in grasps.grasps
           if min(g.pressure_ratio, g.felt_ratio, g.closure_ratio) < 0.9]
    assert not bad, f"weak grasps (index, pressure/first, felt/first): {bad}"
