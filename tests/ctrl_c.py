"""Ctrl-C as a terminal sends it, for tests of long commands: SIGINT to the process group of
a ``teleop`` command once its stderr (read as it comes: progress bars redraw one line) says
it is far enough."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable


def interrupt_when(argv: list[str], ready: Callable[[str], bool], timeout_s: float = 120.0
                   ) -> tuple[int, str, str]:
    """Run ``python -m teleop.cli *argv`` in its own session; once ``ready(stderr so far)``,
    SIGINT the group; ``(exit status, stdout, stderr)``.  Fails if the command ended first."""
    proc = subprocess.Popen([sys.executable, "-m", "teleop.cli", *argv],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True)
    seen: list[str] = []
    said: list[str] = []

    def read(stream, into: list[str]) -> None:  # noqa: ANN001
        while chunk := stream.read1(4096):
            into.append(chunk.decode(errors="replace"))

    readers = [threading.Thread(target=read, args=(proc.stderr, seen), daemon=True),
               threading.Thread(target=read, args=(proc.stdout, said), daemon=True)]
    for r in readers:
        r.start()
    try:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline and proc.poll() is None and not ready("".join(seen)):
            time.sleep(0.05)
        assert proc.poll() is None, "the command ended before it could be interrupted"
        os.killpg(proc.pid, signal.SIGINT)
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    for r in readers:
        r.join(timeout=10)
    return proc.returncode, "".join(said), "".join(seen)
