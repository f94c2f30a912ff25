"""The emulated brain board: model, faults, and the `teleop hand-emulator` process on UDP."""

from __future__ import annotations

import json
import random
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest

from sim.hand_emulator import OVERLOAD_BIT, BoardParams, BrainBoardModel
from sim.hand_emulator_faults import BoardFaults, encode_with_faults
from teleop.cli import main
from teleop.config import load_config
from teleop.devices import takktile_units as U
from teleop.devices.brain_board_packets import (
    ModesPacket,
    StateReceiver,
    TargetsPacket,
    encode_modes,
    encode_targets,
)

HOMES = (1000, -1000, 1000, 0)
INV = (1, -1, 1, -1)


def goal_counts(joint_rad: float) -> tuple[int, int, int, int]:
    zeros = [h * U.RAD_PER_COUNT / 1.42 for h in HOMES[:3]]
    return (*(U.raw_goal(joint_rad, INV[k], zeros[k], 1.42) for k in range(3)),
            U.raw_goal(0.0, -1, 0.0, 1.5))  # type: ignore[return-value]


def model(kind: str = "cylinder", **kw: float) -> BrainBoardModel:
    cfg = load_config(None, [f"hand.sim.object.kind={kind}"])
    m = BrainBoardModel(cfg.hand, BoardParams(homes_counts=HOMES, **kw))  # type: ignore[arg-type]
    m.start()
    return m


def joint(s: object, k: int) -> float:
    return U.joint_from_raw(s.dxl_angle[k], INV[k], HOMES[k] * U.RAD_PER_COUNT / 1.42, 1.42)  # type: ignore[attr-defined]


def test_the_board_closes_on_the_object_pressures_rise_and_the_rate_drops() -> None:
    m = model()
    rest = m.state_at(0.02)
    assert m.period_s() == pytest.approx(0.025)  # 40 Hz free
    m.handle(ModesPacket((2, 2, 2, 2)), 0.03)
    m.handle(TargetsPacket(goal_counts(1.2)), 0.03)
    s = m.state_at(1.5)
    assert all(0.3 < joint(s, k) < 1.2 for k in range(3))  # stopped by the cylinder
    press = np.array(s.pressures[:27]) - np.array(m.tactile_rest[:27])
    assert press.reshape(3, 9).max(axis=1).min() > 50  # every finger feels it
    assert np.abs(np.array(rest.pressures) - m.tactile_rest).max() < 10  # noise only at rest
    assert m.period_s() == pytest.approx(1 / 28)  # all three in contact: 28 Hz
    loads = [U.load_from_raw(s.dxl_load[k], INV[k]) for k in range(3)]
    assert min(loads) > 100  # the tendons pull (positive after the driver's decoding)


def test_velocity_mode_targets_are_speeds_and_idle_has_no_torque() -> None:
    m = model(kind="none")
    m.handle(ModesPacket((1, 1, 1, 1)), 0.0)
    m.handle(TargetsPacket((U.raw_speed(0.5, 1.42),) * 4), 0.0)
    assert m.speeds[0] == U.raw_speed(0.5, 1.42) and m.goals == list(HOMES)
    m.handle(ModesPacket((2, 2, 2, 2)), 0.0)
    m.handle(TargetsPacket(goal_counts(1.0)), 0.0)
    fast = model(kind="none")  # the same move at the servo's full speed
    fast.handle(ModesPacket((2, 2, 2, 2)), 0.0)
    fast.handle(TargetsPacket(goal_counts(1.0)), 0.0)
    slow_rad, fast_rad = joint(m.state_at(0.5), 0), joint(fast.state_at(0.5), 0)
    assert 0.0 < slow_rad < 0.25 < 0.5 < fast_rad  # the 0.5 rad/s ramp holds it back
    m.handle(ModesPacket((0, 0, 0, 0)), 0.5)
    a = joint(m.state_at(0.6), 0)
    assert joint(m.state_at(1.5), 0) < a  # torque off: the base spring opens it


def test_sustained_overload_sets_error_bit_5_and_torque_off_until_modes_again() -> None:
    m = model(overload_units=300.0, load_noise_units=0.0)
    m.handle(ModesPacket((2, 2, 2, 2)), 0.0)
    m.handle(TargetsPacket(goal_counts(3.0)), 0.0)
    t, errs = 0.0, []
    while t < 2.0:
        t += 0.025
        errs.append(m.state_at(t).dxl_error[0])
    assert OVERLOAD_BIT in errs and m.overloaded[0]
    m.handle(ModesPacket((2, 2, 2, 2)), t)
    assert m.state_at(t + 0.025).dxl_error[0] == 0


def test_faults_reach_the_receiver_as_their_drop_reasons() -> None:
    m = model(kind="none")
    rng = random.Random(1)
    for faults, reason in ((BoardFaults(truncate_rate=1.0), "bad_length"),
                           (BoardFaults(bad_magic_rate=1.0), "bad_magic")):
        rx, counts = StateReceiver(), {}
        for i in range(5):
            for out in encode_with_faults(m.state_at(0.025 * (i + 1)), 0.0, faults, rng, {},
                                          counts):
                assert rx.accept(out.data) is None
        assert rx.counts().count(reason) == 5
    counts = {}
    assert encode_with_faults(m.state_at(1.0), 1.0, BoardFaults(loss=1.0), rng, {}, counts) == []
    silent = BoardFaults(silent_after_s=1.0, silent_for_s=0.5)
    assert encode_with_faults(m.state_at(1.1), 1.1, silent, rng, {}, counts) == []
    assert encode_with_faults(m.state_at(1.6), 1.6, silent, rng, {}, counts) != []
    late = encode_with_faults(m.state_at(1.7), 1.7, BoardFaults(late_rate=1.0), rng, {}, {})
    assert late[0].delay_s == pytest.approx(0.06)
    held: dict[int, int] = {}
    stuck = BoardFaults(stuck=((3, -1), (10, 900)))
    outs = [encode_with_faults(m.state_at(2.0 + 0.025 * i), 0.0, stuck, rng, held, {})
            for i in range(3)]
    states = [StateReceiver().accept(o[0].data) for o in outs]
    assert {s.pressures[3] for s in states} == {held[3]}  # type: ignore[union-attr]
    assert {s.pressures[10] for s in states} == {900}  # type: ignore[union-attr]
    assert len({s.pressures[4] for s in states}) > 1  # type: ignore[union-attr]


@pytest.mark.parametrize(("args", "where"), [
    (("--address", "224.0.0.124"), "--address"),
    (("--address", "127.0.0.1", "--multicast"), "--address"),
    (("--address", "nowhere"), "--address"),
    (("--stuck-sensor", "4:1"), "--stuck-sensor"),
    (("--homes", "1,2"), "--homes"),
    (("--loss", "1.5"), "--loss"),
    (("--silent-for", "1"), "--silent-for"),
    (("--set", "hand.sim.object.kind=sphere"), "hand.sim.object.kind"),
])
def test_bad_flags_are_one_line_and_exit_2(args: tuple[str, ...], where: str,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    try:
        status = main(["hand-emulator", *args, "--port", "0", "--duration", "0.1"])
    except SystemExit as exc:  # argparse's own errors
        status = int(exc.code or 0)
    assert status == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and where in lines[0], lines


def test_the_emulator_process_serves_states_over_udp_and_stops_on_sigterm() -> None:
    proc = subprocess.Popen([sys.executable, "-m", "teleop.cli", "hand-emulator", "--port", "0",
                             "--homes", ",".join(map(str, HOMES))],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        host, port = proc.stdout.readline().strip().split(":")
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind(("127.0.0.1", 0))
        sock.settimeout(1.0)
        board = (host, int(port))
        sock.sendto(encode_modes((2, 2, 2, 2)), board)
        rx = StateReceiver()

        def collect(seconds: float) -> list[float]:
            t_end, got = time.monotonic() + seconds, []
            while time.monotonic() < t_end:
                s = rx.accept(sock.recvfrom(4096)[0])
                if s is not None:
                    got.append(s.systime_us / 1e6)
            return got

        free = collect(1.0)
        sock.sendto(encode_targets(goal_counts(1.2)), board)
        collect(1.0)  # closing onto the cylinder
        grasp = collect(1.5)
        sock.close()
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    # the board's own clock, median interval: a scheduling stall of this host is one outlier
    free_hz = 1.0 / float(np.median(np.diff(free)))
    grasp_hz = 1.0 / float(np.median(np.diff(grasp)))
    assert 38.0 < free_hz < 42.0
    assert 26.5 < grasp_hz < 30.0
    assert rx.counts().rejected == 0
    assert "states" in err and "Traceback" not in err


def test_duration_ends_the_run_and_json_holds_the_counters(tmp_path: object,
                                                           capsys: pytest.CaptureFixture[str]
                                                           ) -> None:
    out = f"{tmp_path}/emu.json"
    assert main(["hand-emulator", "--port", "0", "--duration", "1.0", "--json", out]) == 0
    with open(out) as fh:
        data = json.load(fh)
    assert 30 <= data["states"] <= 41  # 1 s at 40 Hz, fingers free
    assert data["sent"] == 0 and data["faults"]["no_peer"] == data["states"]  # nobody asked
    assert capsys.readouterr().out.startswith("127.0.0.1:")


def test_a_taken_port_is_one_line_and_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", 0))
        port = taken.getsockname()[1]
        assert main(["hand-emulator", "--port", str(port), "--duration", "0.1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"--port {port}: cannot bind" in err[0]
