"""Secure mode through the real ZenohBus: intruders cannot get a hand command to the hand.

The hand and the controller run :class:`~teleop.transport.zenoh_bus.ZenohBus` from the config
(``ZenohBus.from_config`` merges ``secure_zenoh_config``), each in its own process.  Intruders
publish valid, encoded HandCommands (with sequence numbers ahead of the real sender's and
within the jump window, so the bus's own sequence filters would let them through) straight at the hand.  As a control, the same
intruder without security reaches the hand, so it is the security layer that stops it.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from test_secure_network import _free_port, _result, _start, _wait_ready

from teleop.security.certs import create_certs

pytestmark = pytest.mark.network

BUS_NODE = Path(__file__).with_name("_bus_node.py")
SESSION = "secbus"
CONTROLLER_ANGLE = 0.5


def _start_bus(role: str, overrides: list[str]) -> subprocess.Popen[str]:
    spec = {"role": role, "overrides": overrides, "angle": CONTROLLER_ANGLE}
    return subprocess.Popen([sys.executable, str(BUS_NODE), json.dumps(spec)],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _run(cert_dir: Path, secure: bool, intruders: dict[str, dict]) -> dict[str, dict]:
    proto = "tls" if secure else "tcp"
    p_ctrl, p_hand = _free_port(), _free_port()
    common = [f"session.name={SESSION}", f"zenoh.endpoint='{proto}/127.0.0.1:{p_ctrl}'"]
    if secure:
        common += ["security.enabled=true", f"security.cert_dir='{cert_dir}'"]
    controller = _start_bus("controller", common)
    _wait_ready(controller)
    hand = _start_bus("hand", common + [f"zenoh.listen=['{proto}/127.0.0.1:{p_hand}']"])
    _wait_ready(hand)
    procs = {}
    for angle, case in intruders.items():
        spec = {"cert_dir": str(cert_dir), "session": SESSION, "run_s": 2.5,
                "connect": [f"{proto}/127.0.0.1:{p_hand}", f"{proto}/127.0.0.1:{p_ctrl}"],
                "encode_hand_command": True, "pub": [["hand_command", angle]], **case}
        procs[angle] = _start(spec)
    for proc in procs.values():
        _wait_ready(proc)
    out = {angle: _result(proc) for angle, proc in procs.items()}
    out["@hand"] = _result(hand)
    out["@controller"] = _result(controller)
    return out


@pytest.fixture(scope="module")
def cert_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("buscerts")
    create_certs(d)
    return d


def test_intruders_cannot_command_the_hand(cert_dir: Path) -> None:
    intruders = {
        "3.0": {"role": "master"},  # valid credentials, wrong role
        "3.1": {"role": "hand"},  # valid credentials, wrong role
        "3.2": {"role": "controller", "tamper": {"drop_auth": True}},  # no user/password
        "3.3": {"role": "controller", "tamper": {"password": "hunter2"}},  # wrong password
    }
    out = _run(cert_dir, secure=True, intruders=intruders)
    assert out["@hand"]["angles"] == [CONTROLLER_ANGLE]
    assert out["3.0"]["peers"] >= 1 and out["3.1"]["peers"] >= 1  # connected, yet denied
    assert out["3.2"]["peers"] == 0 and out["3.3"]["peers"] == 0  # not even connected


def test_control_without_security_the_intruder_gets_through(cert_dir: Path) -> None:
    out = _run(cert_dir, secure=False, intruders={"3.0": {"role": "master", "secure": False}})
    assert 3.0 in out["@hand"]["angles"]
