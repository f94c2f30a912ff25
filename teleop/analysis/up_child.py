"""``teleop up`` as a child process, run to its end: the live sweep's points and the
dashboard benchmark's runs.

A child that fails or overruns is a one-line :class:`~teleop.errors.DeviceError` naming what
ran it and the last line the child printed (the CLI prints it and exits 1), not a traceback.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

from teleop.errors import DeviceError


def run_up(args: Sequence[str], *, timeout_s: float, what: str,
           tree: Path | None = None) -> subprocess.CompletedProcess[str]:
    """Run ``python -m teleop.cli up ARGS`` and wait for it; with ``tree`` (a source tree of
    this project) that tree is first on the path and the working directory."""
    cmd = [sys.executable, "-m", "teleop.cli", "up", *args]
    env = None if tree is None else dict(os.environ, PYTHONPATH=str(tree))
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False,
                              timeout=timeout_s, cwd=tree, env=env)
    except subprocess.TimeoutExpired:
        raise DeviceError(f"{what}: teleop up did not finish within {timeout_s:.0f} s") \
            from None
    if proc.returncode != 0:
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-1:] or ["no output"]
        where = "" if tree is None else f" (tree {tree})"
        raise DeviceError(f"{what}: teleop up{where} exited with status {proc.returncode}: "
                          f"{tail[0]}")
    return proc


__all__ = ["run_up"]
