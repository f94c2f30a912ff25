"""Secure mode at the service level: intruders cannot make the (simulated) hand move.

The real hand service (``teleop run hand``, simulated hand, its own process) runs with
``config/secure.toml``.  A stand-in controller holding the controller's credentials declares
the controller's liveliness token and sends hold-open commands (0 rad, no energy), so the
hand's loop starts (it waits for the controller's first command).  Intruders
(valid credentials of the wrong role, no credentials, a wrong password) send valid hand
commands that close the fingers to 2.5 rad with plenty of energy, straight to the hand.  The
hand's recording shows the commands never arrived and the fingers never moved.  Control: the
same intruder without security does move the hand.  Least privilege: the hand service also
runs, connecting only, from a directory holding nothing but the CA and its own certificate, key
and password file (no other role's password).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_secure_network import _free_port, _result, _start, _wait_ready

from teleop.recording import read_recording
from teleop.security.certs import create_certs

pytestmark = [pytest.mark.network, pytest.mark.slow]

REPO = Path(__file__).resolve().parents[3]
SESSION = "sechand"
INTRUDER_ANGLE = "2.5"


def _run_hand(tmp: Path, secure: bool, intruders: list[dict],
              own_files_only: bool = False) -> tuple[dict, list[dict]]:
    """Run the hand service ~3 s under attack; its recording's key figures and the intruders'.

    ``own_files_only``: the hand only connects, from a directory holding just its own files.
    """
    cert_dir = tmp / "certs"
    if secure:
        create_certs(cert_dir)
    hand_dir = cert_dir
    if own_files_only:
        hand_dir = tmp / "hand-certs"
        hand_dir.mkdir()
        for name in ("ca.pem", "hand.pem", "hand.key", "hand.credentials"):
            (hand_dir / name).write_bytes((cert_dir / name).read_bytes())
    proto = "tls" if secure else "tcp"
    p_ctrl, p_hand = _free_port(), _free_port()
    ctrl_ep, hand_ep = f"{proto}/127.0.0.1:{p_ctrl}", f"{proto}/127.0.0.1:{p_hand}"
    base = {"cert_dir": str(cert_dir), "session": SESSION, "secure": secure}
    # the hand ticks once the controller's first command arrives: in secure mode (where the
    # intruders are shut out) the stand-in sends hold-open commands (0 rad, no energy)
    holding = {"pub": [["hand_command", "0.0"]], "encode_hand_command": True} if secure else {}
    stand_in = _start({**base, "role": "controller", "listen": [ctrl_ep], "token": True,
                       **holding})
    _wait_ready(stand_in)
    argv = [sys.executable, "-m", "teleop.cli", "run", "hand", "--duration", "3",
            "--dashboard", "off", "--record", str(tmp / "rec"), "--no-realtime",
            "--wait-peers", "15", "--set", f"session.name={SESSION}",
            "--set", f"zenoh.endpoint='{ctrl_ep}'"]
    if not own_files_only:
        argv += ["--set", f"zenoh.listen=['{hand_ep}']"]
    if secure:
        argv += ["--config", str(REPO / "config" / "secure.toml"),
                 "--set", f"security.cert_dir='{hand_dir}'"]
    hand = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=tmp)
    # the intruders publish until the hand service has finished (stdin closed after): however
    # late the hand's process comes up on a loaded machine, its whole run is under attack
    procs = [_start({**base, "connect": [hand_ep, ctrl_ep], "run_s": None,
                     "encode_hand_command": True, "energy_j": 5.0,
                     "pub": [["hand_command", INTRUDER_ANGLE]], **case}) for case in intruders]
    for proc in procs:
        _wait_ready(proc)
    try:
        out, err = hand.communicate(timeout=40)
    except subprocess.TimeoutExpired:
        hand.kill()
        hand.communicate()
        for proc in procs:
            proc.kill()
        raise AssertionError("hand service hung") from None
    results = [_result(proc) for proc in procs]  # closes each one's stdin: it stops
    _result(stand_in)
    assert hand.returncode == 0, err
    rec = read_recording(tmp / "rec" / "hand.csv")
    desired = np.nanmax(np.column_stack([rec.column(f"setpoint_desired_rad_f{i}")
                                         for i in (1, 2, 3)]))
    proximal = np.nanmax(np.abs(np.column_stack([rec.column(f"proximal_angle_rad_f{i}")
                                                 for i in (1, 2, 3)])))
    return {"samples": len(rec), "desired_max_rad": float(desired),
            "proximal_max_rad": float(proximal)}, results


def test_intruders_cannot_move_the_hand(tmp_path: Path) -> None:
    figures, results = _run_hand(tmp_path, True, [
        {"role": "master"},  # valid credentials, wrong role
        {"role": "hand"},  # valid credentials, wrong role
        {"role": "controller", "tamper": {"drop_auth": True}},  # no user/password
        {"role": "controller", "tamper": {"password": "letmein"}},  # wrong password
    ])
    assert figures["samples"] > 60  # the loop ran (40 Hz for 3 s)
    assert figures["desired_max_rad"] < 0.05  # no intruder command reached the hand
    assert figures["proximal_max_rad"] < 0.02  # and the fingers did not move
    assert results[0]["peers"] >= 1 and results[1]["peers"] >= 1  # connected, yet denied
    assert results[2]["peers"] == 0 and results[3]["peers"] == 0  # refused outright


def test_hand_service_runs_on_its_own_files_only(tmp_path: Path) -> None:
    # connecting only, the hand holds no dictionary and no other role's password, yet it
    # authenticates to the controller and its loop runs on the controller's commands
    figures, _ = _run_hand(tmp_path, True, [], own_files_only=True)
    assert not (tmp_path / "hand-certs" / "credentials.txt").exists()
    assert figures["samples"] > 60


def test_control_without_security_the_intruder_moves_the_hand(tmp_path: Path) -> None:
    # the intruder starts at seq 1 like a fresh controller, so its energy total is credited
    figures, _ = _run_hand(tmp_path, False, [{"role": "master", "first_seq": 1}])
    # the intruder's angle is approached at the servo's 4 rad/s until the fingers touch the
    # simulated cylinder; from then on the hand's touch cap holds its commands, which echo no
    # hand state (``hand_echo_t_s`` = -1: they never saw the touch), at contact + F_max / k
    # (0.67-0.75 rad, after a 1.0 rad peak before the touch); far from the secure runs' < 0.05
    # either way, and never beyond the angle sent
    assert 0.5 < figures["desired_max_rad"] <= float(INTRUDER_ANGLE) + 1e-9
    assert figures["proximal_max_rad"] > 0.05
