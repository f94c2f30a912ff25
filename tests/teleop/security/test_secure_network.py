"""Secure mode over real zenoh sessions (separate processes) on 127.0.0.1.

Topology as in ``teleop up``: the controller listens, the hand connects to it (and listens too,
so that intruders can reach it directly).  Intruders connect to both and publish master state
and hand commands on the real keys ``teleop/<session>/<role>/<signal>``.  Only the master's
master state and the controller's hand commands may arrive.  Connecting nodes hold only their
own password (no dictionary).  Two observers (the read-only role of a dashboard) publish too:
one a zenoh client of the controller (which routes the session to it), one a peer connected to
the controller and the hand directly.
"""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from teleop.security.certs import create_certs
from teleop.transport.keys import data_key

pytestmark = pytest.mark.network

NODE = Path(__file__).with_name("_secure_node.py")
SESSION = "sectest"
RUN_S = 2.5


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _start(spec: dict) -> subprocess.Popen[str]:  # type: ignore[type-arg]
    return subprocess.Popen([sys.executable, str(NODE), json.dumps(spec)], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait_ready(proc: subprocess.Popen[str], timeout_s: float = 20.0) -> None:
    assert proc.stdout is not None
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if line.startswith("READY"):
            return
        if not line and proc.poll() is not None:
            break
    proc.kill()
    raise AssertionError(f"node did not start: {proc.stderr.read() if proc.stderr else ''}")


def _result(proc: subprocess.Popen[str], timeout_s: float = 30.0) -> dict:
    try:
        out, err = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        raise AssertionError("node hung") from None
    for line in out.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[len("RESULT "):])  # type: ignore[no-any-return]
    raise AssertionError(f"node gave no result (rc={proc.returncode}): {out} {err}")


@pytest.fixture(scope="module")
def cert_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("certs")
    create_certs(d)
    return d


@pytest.fixture(scope="module")
def run_outcome(cert_dir: Path) -> dict[str, dict]:
    """Run the legitimate controller and hand plus every intruder once; collect what arrived."""
    p_ctrl, p_hand = _free_port(), _free_port()
    tls_ctrl, tls_hand = f"tls/127.0.0.1:{p_ctrl}", f"tls/127.0.0.1:{p_hand}"
    base = {"cert_dir": str(cert_dir), "session": SESSION}
    both = ["master_state", "hand_command"]
    controller = _start({**base, "role": "controller", "listen": [tls_ctrl],
                         "pub": [["hand_command", "controller"], ["master_state", "controller"]]})
    _wait_ready(controller)
    # a rogue peer holding the master's credentials, with its own ACL removed, that the hand
    # connects to: the hand's own ingress check must refuse its hand commands
    p_rogue = _free_port()
    rogue = _start({**base, "role": "master", "listen": [f"tls/127.0.0.1:{p_rogue}"],
                    "tamper": {"drop_acl": True}, "run_s": RUN_S + 1.0,
                    "pub": [["hand_command", "rogue"], ["master_state", "rogue"]]})
    _wait_ready(rogue)
    hand = _start({**base, "role": "hand", "listen": [tls_hand],
                   "connect": [tls_ctrl, f"tls/127.0.0.1:{p_rogue}"],
                   "pub": [["hand_state", "hand"]]})
    _wait_ready(hand)
    intr = {"connect": [tls_ctrl, tls_hand], "run_s": RUN_S}
    cases = {
        "master": {"role": "master"},
        "hand_creds": {"role": "hand"},
        "no_credentials": {"role": "master", "tamper": {"drop_auth": True}},
        "wrong_password": {"role": "controller", "tamper": {"password": "guess"}},
        "no_client_cert": {"role": "controller", "tamper": {"drop_client_cert": True}},
        "plaintext": {"role": "controller", "secure": False,
                      "connect": [f"tcp/127.0.0.1:{p_ctrl}", f"tcp/127.0.0.1:{p_hand}"]},
        "observer": {"role": "observer", "mode": "client", "connect": [tls_ctrl]},
        "observer_peer": {"role": "observer"},
    }
    procs = {}
    for tag, case in cases.items():
        spec = {**base, **intr, **case, "pub": [[sig, tag] for sig in both]}
        procs[tag] = _start(spec)
    for proc in procs.values():
        _wait_ready(proc)
    outcome = {tag: _result(proc) for tag, proc in procs.items()}
    outcome["rogue"] = _result(rogue)
    # communicate() closes a receiver's stdin, which stops it
    outcome["@controller"] = _result(controller)
    outcome["@hand"] = _result(hand)
    return outcome


def _tags(got: list[list[str]], signal: str) -> set[str]:
    key = data_key(SESSION, signal)
    return {tag for k, tag in got if k == key}


def test_only_the_controller_commands_the_hand(run_outcome: dict[str, dict]) -> None:
    assert _tags(run_outcome["@hand"]["got"], "hand_command") == {"controller"}


def test_only_the_master_publishes_master_state(run_outcome: dict[str, dict]) -> None:
    # "rogue" holds the master's credentials too, so its master state is accepted
    assert _tags(run_outcome["@controller"]["got"], "master_state") == {"master", "rogue"}
    # the controller may not forge master state either (refused by the hand, which connected)
    assert "controller" not in _tags(run_outcome["@hand"]["got"], "master_state")


def test_legitimate_traffic_flows(run_outcome: dict[str, dict]) -> None:
    assert _tags(run_outcome["@controller"]["got"], "hand_state") == {"hand"}


@pytest.mark.parametrize("tag", ["no_credentials", "wrong_password", "no_client_cert",
                                 "plaintext"])
def test_unauthenticated_sessions_cannot_connect(run_outcome: dict[str, dict], tag: str) -> None:
    assert run_outcome[tag]["peers"] == 0
    for who in ("@controller", "@hand"):
        assert tag not in {t for _, t in run_outcome[who]["got"]}


def test_valid_credentials_for_the_wrong_role_are_denied(run_outcome: dict[str, dict]) -> None:
    # the hand's credentials connect (2 peers) but publish nothing the others accept
    assert run_outcome["hand_creds"]["peers"] >= 2
    for who in ("@controller", "@hand"):
        assert "hand_creds" not in {t for _, t in run_outcome[who]["got"]}
    # the hand connected out to a rogue master (no ACL of its own): its commands are refused
    assert run_outcome["rogue"]["peers"] >= 1
    assert "rogue" not in _tags(run_outcome["@hand"]["got"], "hand_command")
    # the master connects and may publish master state, but never command the hand
    assert run_outcome["master"]["peers"] >= 2
    assert "master" not in _tags(run_outcome["@hand"]["got"], "hand_command")


def test_signals_go_only_to_their_receiver(run_outcome: dict[str, dict]) -> None:
    # egress confinement: the master never sees hand commands, the hand never master state
    assert _tags(run_outcome["master"]["got"], "hand_command") == set()
    assert "master" not in _tags(run_outcome["@hand"]["got"], "master_state")
    assert _tags(run_outcome["hand_creds"]["got"], "hand_command") == {"controller"}


def test_plaintext_listen_endpoint_refused_by_zenoh(cert_dir: Path) -> None:
    port = _free_port()
    proc = _start({"cert_dir": str(cert_dir), "session": SESSION, "role": "hand",
                   "listen": [f"tls/127.0.0.1:{port}"], "open_only": True,
                   "overrides": [f"zenoh.connect=['tls/127.0.0.1:{port}']"]})
    out, _ = proc.communicate(timeout=30)
    assert "OPENED" in out
    # the same node with a tcp listener slipped past the config check: zenoh itself refuses it
    proc = subprocess.Popen(
        [sys.executable, "-c", _TCP_SLIP, str(cert_dir), str(port)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out, err = proc.communicate(timeout=30)
    assert "OPEN-ERROR" in out and "tcp" in out.lower(), (out, err)


_TCP_SLIP = """
import sys, zenoh
from teleop.config import load_config
from teleop.security.zenoh_secure import secure_zenoh_config
cfg = load_config(None, ["security.enabled=true", f"security.cert_dir='{sys.argv[1]}'",
                         "zenoh.endpoint='tls/127.0.0.1:7447'"])
zc = zenoh.Config()
zc.insert_json5("scouting/multicast/enabled", "false")
for k, v in secure_zenoh_config(cfg, "hand").items():
    zc.insert_json5(k, v)
zc.insert_json5("listen/endpoints", f'["tcp/127.0.0.1:{sys.argv[2]}"]')
try:
    s = zenoh.open(zc)
except Exception as exc:
    print("OPEN-ERROR", exc)
else:
    print("OPENED")
    s.close()
"""


def test_observer_reads_the_session_but_publishes_nothing(run_outcome: dict[str, dict]) -> None:
    # the dashboard's session, a client of the controller, receives the master's state (and the
    # controller's hand commands) through the controller
    obs = run_outcome["observer"]["got"]
    assert "master" in _tags(obs, "master_state")
    assert "controller" in _tags(obs, "hand_command")
    assert "hand" in _tags(obs, "hand_state")
    # but nothing it publishes is accepted: not routed by the controller, not taken by the hand
    # even from a direct link (the peer observer connected to both)
    assert run_outcome["observer_peer"]["peers"] >= 2
    for who in ("@controller", "@hand"):
        got = {t for _, t in run_outcome[who]["got"]}
        assert not {"observer", "observer_peer"} & got, who
    assert _tags(run_outcome["@hand"]["got"], "hand_command") == {"controller"}
