"""``teleop watch``: a dashboard session as the observer role, over real zenoh, secure mode,
against the three services ``teleop up`` starts."""

from __future__ import annotations

import json
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from teleop.security.certs import create_certs

pytestmark = [pytest.mark.network, pytest.mark.slow]


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _teleop(*args: str) -> list[str]:
    return [sys.executable, "-m", "teleop.cli", *args]


def test_watch_observes_a_secure_session_and_a_wrong_password_sees_nothing(
        tmp_path: Path) -> None:
    from rerun.chunk import RrdReader

    certs = tmp_path / "certs"
    create_certs(certs)
    port = _free_port()
    sets = [f"zenoh.endpoint='tls/127.0.0.1:{port}'", f"session.name=obs{port}",
            "security.enabled=true", f"security.cert_dir='{certs}'"]
    flags = [x for s in sets for x in ("--set", s)]
    up = subprocess.Popen(_teleop("up", *flags, "--duration", "60", "--dashboard", "off",
                                  "--no-realtime"),
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert up.stdout is not None
        t0 = time.monotonic()
        for line in up.stdout:  # "teleop up: running ..." once all three are ready
            if "running" in line or time.monotonic() - t0 > 60:
                break
        rrd, out = tmp_path / "obs.rrd", tmp_path / "obs.json"
        w = subprocess.run(_teleop("watch", *flags, "--duration", "3", "--dashboard",
                                   f"save:{rrd}", "--json", str(out)),
                           capture_output=True, text=True, timeout=60)
        assert w.returncode == 0, w.stderr
        doc = json.loads(out.read_text())
        assert doc["secure"] and doc["rejected"] == 0
        for sig in ("master_state", "force_command", "hand_command", "hand_state"):
            assert doc["received"][sig] > 10, (sig, doc["received"])
        found = {c.entity_path.lstrip("/") for c in RrdReader(rrd).stream()
                 if not c.is_static and c.num_rows > 0}
        assert {"observer/master_state/grip_position_m",
                "observer/hand_state/servo_fault_trips"} <= found
        # the observer's identity is what lets it in: a wrong password gets no session
        bad = subprocess.run(_teleop("watch", *flags, "--set", "security.observer.password=x",
                                     "--duration", "2", "--dashboard", "off", "--json", "-"),
                             capture_output=True, text=True, timeout=60)
        if bad.returncode == 0:
            assert sum(json.loads(bad.stdout)["received"].values()) == 0
        else:
            assert bad.returncode == 2 and "Traceback" not in bad.stderr
            assert "cannot open the observer session" in bad.stderr.strip().splitlines()[-1]
    finally:
        up.send_signal(signal.SIGINT)
        try:
            up.wait(15)
        except subprocess.TimeoutExpired:
            up.kill()
            up.wait()
