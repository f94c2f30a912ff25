"""False-alarm scan of the yielding-contact and unseen-contact guards and the gain cross-check
on the simulated hand.

    python tests/teleop/control/yield_scan.py [SECONDS] [DELAYS] [KEY=VALUE ...]

Lockstep, defaults, seed 1: every operator style (soft, relaxed, hard) x every elastic object
of the robustness grid (soft cylinder, stiff cylinder, block) and free air x each one-way
delay of
``DELAYS`` (comma-separated seconds, both links; default ``0,0.2``), ``SECONDS`` of virtual
time each (default 30), extra config overrides after them (e.g.
``links.master_controller.loss=0.2 links.controller_hand.loss=0.2``).  Prints, per run, the
most fingers the hand flagged as yielding, as stalled on a contact its cells do not see, and
as reading less than the servo's load implies (:mod:`teleop.control.gain_check`), at once (0
everywhere is no false alarm: the cells work and nothing yields) and the smallest
margin of the physical energy audit.  docs/controllers.md quotes its figures.
"""

from __future__ import annotations

import itertools
import sys
import time
from typing import Any

import numpy as np

from services.lockstep import run_lockstep
from teleop.analysis.sweep_objects import with_object
from teleop.config import load_config

OPERATORS = ("soft", "relaxed", "hard")
ELASTIC = ("soft-cylinder", "stiff-cylinder", "block", "free-air")


def scan(seconds: float, delays_s: tuple[float, ...], extra: list[str]) -> int:
    """Run the scan, print a line per run; the number of runs with a finger flagged."""
    flagged_runs = 0
    for op, obj, delay in itertools.product(OPERATORS, ELASTIC, delays_s):
        cfg = with_object(load_config(None, [
            f"master.virtual.style={op}", f"links.master_controller.delay_s={delay}",
            f"links.controller_hand.delay_s={delay}", *extra]), obj)
        most = [0, 0, 0]

        def hook(_t: float, ctx: Any, most: list[int] = most) -> None:
            if ctx.hand:
                most[0] = max(most[0], ctx.hand._yielding)
                most[1] = max(most[1], ctx.hand._unseen)
                most[2] = max(most[2], ctx.hand._cells_low)

        t0 = time.perf_counter()
        r = run_lockstep(cfg, seconds, seed=1, hook=hook)
        margin = float(np.nanmin(r.audit_margin_j)) if r.has_audit else float("nan")
        flagged_runs += max(most) > 0
        print(f"{op:8} {obj:15} {delay * 1000:5.0f} ms  fingers flagged yielding {most[0]} "
              f"unseen {most[1]} cells low {most[2]}  "
              f"audit margin {margin:.4f} J  ({time.perf_counter() - t0:.1f} s)", flush=True)
    return flagged_runs


if __name__ == "__main__":
    secs = float(sys.argv[1]) if len(sys.argv) > 1 else 30.0
    delays = tuple(float(v) for v in (sys.argv[2] if len(sys.argv) > 2 else "0,0.2").split(","))
    n = scan(secs, delays, sys.argv[3:])
    print(f"{n} run(s) with a finger flagged")
