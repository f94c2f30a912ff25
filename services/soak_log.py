"""What a service writes for ``teleop faults --soak`` (``teleop run --soak-log DIR``).

Two files per process, named ``<role>-<pid>`` so that a restarted controller writes its own:

* ``.timing``: every loop tick's deadline (s from the session epoch), lateness and, for a
  tick that ended a stall, the stall's true lateness (from the first deadline it missed);
  binary records of :data:`TIMING_DTYPE`, appended in blocks, so the loop keeps no history in
  memory however long it runs;
* ``.jsonl``: a status line ten times a second: the watchdog, the bus's rejections so far,
  the tank's initial energy, the trigger's position (master) or the sensors in contact
  (hand) and, where the backend simulates physics (virtual operator,
  simulated hand), the physical energy audit of its port (``sim.operator``/``sim.audit``:
  delivered and taken so far, from the physics, not the controller's books).

The parent reads both after (or during) the run: :func:`read_timing`, :func:`read_status`.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, TextIO

import numpy as np

TIMING_DTYPE = np.dtype([("t_s", "<f8"), ("late_s", "<f4"), ("stall_s", "<f4")])
BLOCK = 1024  # ticks per write (about 1 s at 1 kHz)
STATUS_HZ = 10.0


class SoakLog:
    """The writer of one service process (the tick thread only)."""

    def __init__(self, directory: Path, role: str, pid: int, epoch_s: float, rate_hz: float
                 ) -> None:
        stem = directory / f"{role}-{pid}"
        self.role = role
        self.epoch_s = epoch_s
        self._timing = open(stem.with_suffix(".timing"), "ab")  # noqa: SIM115 - closed in close()
        self._status: TextIO = open(stem.with_suffix(".jsonl"), "a")  # noqa: SIM115
        self._buf = np.zeros(BLOCK, dtype=TIMING_DTYPE)
        self._n = 0
        self._status_every = max(1, round(rate_hz / STATUS_HZ))
        self._count = 0

    def timing(self, deadline_s: float, late_s: float, stall_s: float) -> None:
        """One tick's timing (a :meth:`services.runtime.RateLoop.run` ``timing`` callback)."""
        self._buf[self._n] = (deadline_s - self.epoch_s, late_s, stall_s)
        self._n += 1
        if self._n == BLOCK:
            self._flush_timing()

    def _flush_timing(self) -> None:
        self._buf[: self._n].tofile(self._timing)
        self._timing.flush()
        self._n = 0

    def due(self) -> bool:
        """Whether this tick writes a status line (call once per tick)."""
        self._count += 1
        return self._count % self._status_every == 0

    def status(self, t_s: float, watchdog: float, rejects: int, initial_j: float,
               audit_j: tuple[float, float] | None, **extra: float) -> None:
        """One status line (``audit_j``: delivered, taken; None without simulated physics;
        ``extra``: role-specific values, e.g. the trigger's position or the hand's contacts)."""
        d: dict[str, Any] = {"t_s": round(t_s - self.epoch_s, 4), "wd": int(watchdog > 0.5),
                             "rejects": rejects, "initial_j": initial_j, **extra}
        if audit_j is not None:
            d["audit_delivered_j"], d["audit_taken_j"] = audit_j
        self._status.write(json.dumps(d) + "\n")
        self._status.flush()

    def close(self) -> None:
        """Write what is buffered and close both files."""
        self._flush_timing()
        self._timing.close()
        self._status.close()


def read_timing(path: Path) -> np.ndarray:
    """The records of a ``.timing`` file (a partial last record is ignored)."""
    raw = path.read_bytes()
    n = len(raw) // TIMING_DTYPE.itemsize
    return np.frombuffer(raw[: n * TIMING_DTYPE.itemsize], dtype=TIMING_DTYPE)


def read_status(path: Path) -> list[dict[str, float]]:
    """The status lines of a ``.jsonl`` file (a partial last line is ignored)."""
    out: list[dict[str, float]] = []
    for line in path.read_text().splitlines():
        try:
            d = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(d, dict) and math.isfinite(float(d.get("t_s", math.nan))):
            out.append(d)
    return out
