"""``teleop budget``: progress while it runs, and Ctrl-C reports the grasps completed.

A ``--seconds 600`` budget runs for minutes; before, it printed nothing until the end and a
Ctrl-C lost the whole run.  The real command, interrupted as a terminal does (SIGINT to its
process group) once its progress bar shows a few grasps simulated.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path


def test_ctrl_c_on_teleop_budget_reports_the_grasps_done_and_exits_130(tmp_path: Path) -> None:
    out = tmp_path / "budget.json"
    proc = subprocess.Popen([sys.executable, "-m", "teleop.cli", "budget", "--seconds", "100",
                             "--json", str(out)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, start_new_session=True)
    seen: list[str] = []

    def read() -> None:
        assert proc.stderr is not None
        while chunk := proc.stderr.read1(4096):
            seen.append(chunk.decode(errors="replace"))

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        deadline = time.monotonic() + 120.0
        while time.monotonic() < deadline and proc.poll() is None:
            done = [int(p) for p in re.findall(r"\] +(\d+)% ", "".join(seen))]
            if done and max(done) >= 12:  # 12 simulated seconds: two 4.5 s grasp cycles
                break
            time.sleep(0.05)
        assert proc.poll() is None, "the run ended before it could be interrupted"
        os.killpg(proc.pid, signal.SIGINT)
        stdout, _ = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    reader.join(timeout=5)
    err = "".join(seen)
    assert proc.returncode == 130, err[-500:]
    assert "interrupted at" in err.splitlines()[-1]
    doc = json.loads(out.read_text())
    assert doc["interrupted"] is True and 12.0 <= doc["seconds"] < 100.0
    assert len(doc["grasps"]) >= 2 and doc["grasps"][-1]["t_end_s"] <= doc["seconds"]
    assert "weakest over the first" in stdout.decode()
