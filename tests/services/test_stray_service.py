"""``teleop run`` of a role already running in the session: refused at its start, in one line.

Real processes over real zenoh on 127.0.0.1 (the ``teleop up`` star: the controller listens,
the master connects); see teleop.transport.roster for why the controller answers for the
master.
"""

from __future__ import annotations

import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from teleop.security.certs import create_certs
from tests.services.test_up import free_port, teleop

REPO = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.network


def _spawn(role: str, common: tuple[str, ...]) -> tuple[subprocess.Popen[str], queue.Queue[str]]:
    proc = subprocess.Popen([sys.executable, "-m", "teleop.cli", "run", role, *common,
                             "--duration", "60"], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    lines: queue.Queue[str] = queue.Queue()

    def pump() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.put(line.rstrip("\n"))

    threading.Thread(target=pump, daemon=True).start()
    return proc, lines


def _wait_line(lines: queue.Queue[str], text: str, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    seen = []
    while time.monotonic() < deadline:
        try:
            line = lines.get(timeout=0.1)
        except queue.Empty:
            continue
        seen.append(line)
        if text in line:
            return
    pytest.fail(f"no line with {text!r} in {timeout_s} s: {seen}")


@pytest.mark.parametrize("secure", [False, True], ids=["plain", "secure"])
def test_a_stray_master_is_refused_and_the_running_one_carries_on(tmp_path: Path,
                                                                  secure: bool) -> None:
    """In secure mode too (TLS, passwords and access control: the query and its answer are
    let through, the stray holding the master's own credentials)."""
    common: tuple[str, ...] = ("--set", "session.name=stray", "--no-realtime")
    if secure:
        create_certs(tmp_path / "certs")
        common += ("--config", str(REPO / "config" / "secure.toml"),
                   "--set", f"security.cert_dir='{tmp_path / 'certs'}'",
                   "--set", f"zenoh.endpoint='tls/127.0.0.1:{free_port()}'")
    else:
        common += ("--set", f"zenoh.endpoint=tcp/127.0.0.1:{free_port()}")
    ctl, ctl_lines = _spawn("controller", common)
    master, master_lines = _spawn("master", common)
    try:
        _wait_line(master_lines, "master: waiting for", 60.0)  # its token is out
        t0 = time.monotonic()
        stray = teleop("run", "master", *common, "--duration", "5", timeout=60)
        took_s = time.monotonic() - t0
        assert stray.returncode == 2, stray.stdout + stray.stderr
        err = stray.stderr.strip()
        assert "Traceback" not in err and len(err.splitlines()) == 1
        assert "a master is already running in session 'stray'" in err
        assert "ready master" not in stray.stdout  # refused before anything started
        assert took_s < 30.0
        # another role is not refused: a hand starts and the controller starts ticking
        hand = teleop("run", "hand", *common, "--duration", "1", timeout=120)
        assert hand.returncode == 0, hand.stdout + hand.stderr
        assert master.poll() is None and ctl.poll() is None  # the first two still run
    finally:
        for p in (master, ctl):
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        codes = [p.wait(timeout=15) for p in (master, ctl)]
    assert codes == [0, 0]
