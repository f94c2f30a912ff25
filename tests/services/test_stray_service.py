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


@pytest.mark.parametrize("secure", [True], ids=["secure"])
def test_a_stray_master_is_refused_and_the_running_one_carries_on(tmp_path: Path,
                                                                  secure: bool) -> None:
    """In secure mode (TLS, passwords and access control: the query and its answer are let
    through, the stray holding the master's own credentials).  Plain mode takes the same way
    through ``teleop run`` and passes too (``[False, True]`` above; one mode in CI for its
    time; the plain probe itself is tested in tests/teleop/transport/test_roster.py)."""
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
    hand: subprocess.Popen[str] | None = None
    try:
        _wait_line(master_lines, "master: waiting for", 60.0)  # its token is out
        t0 = time.monotonic()
        stray = teleop("run", "master", *common, "--duration", "5", timeout=60)
        took_s = time.monotonic() - t0
        assert stray.returncode == 2, stray.stdout + stray.stderr
        err = stray.stderr.strip()
        assert "Traceback" not in err and len(err.splitlines()) == 1
        assert "a master is already running in session 'stray'" in err
        assert "ready master" not in stray.stdout
        assert took_s < 30.0
        # another role is not refused: the hand starts, and the controller starts ticking
        hand, hand_lines = _spawn("hand", common)
        _wait_line(ctl_lines, "status ", 60.0)  # the controller's once-a-second line
        # a second hand is refused before its device starts: its backend, a servo bus on a
        # port that does not exist, would fail its start with a device error instead
        stray_hand = teleop("run", "hand", *common, "--duration", "5",
                            "--set", "hand.backend=dynamixel",
                            "--set", "hand.dynamixel.port=/nonexistent/ttyUSB9", timeout=60)
        assert stray_hand.returncode == 2, stray_hand.stdout + stray_hand.stderr
        assert "a hand is already running in session 'stray'" in stray_hand.stderr
        assert "ttyUSB9" not in stray_hand.stderr
        assert all(p.poll() is None for p in (master, ctl, hand))  # the first three run on
    finally:
        running = [p for p in (master, hand, ctl) if p is not None]
        for p in running:
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        codes = [p.wait(timeout=15) for p in running]
    assert codes == [0] * len(running)
