"""Quick grasps of a yielding object with cells reading low: the yield guard in the harness.

    python tests/teleop/control/yield_harness_scan.py [--no-set-check] [--seconds S]

The closed-loop harness (``_ctl_harness``, its own physics and energy audit) with 0.1 J tanks
against the object that yields while pressed (the box pushed across a table of
``test_assumptions.PUSH``), over operators of 500-12,000 N/m x grasps of 2-8 s x tactile
gains of 0.2-0.5 (below the margin: the cells charge ``m g < 1`` of the work).  Prints one
line per run: the most fingers flagged at once and the audit's smallest margin, then how many
runs broke the bound and how many of those were never flagged.  The end-of-contact set
check (:func:`teleop.control.yield_guard.took_a_set`, ``yield_set_check``) is on here;
``--no-set-check`` runs the same with it off (the default), for the comparison
docs/controllers.md quotes.
"""

from __future__ import annotations

import argparse
import itertools
import sys
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[3]))

from _ctl_harness import audit_failure, initial_tank_j, run_loop  # noqa: E402
from test_assumptions import P_SET, PUSH, SUITE, P  # noqa: E402

OPERATORS_N_PER_M = (500.0, 1000.0, 2000.0, 3000.0, 5000.0, 8000.0, 12000.0)
PERIODS_S = (2.0, 3.0, 4.0, 5.0, 6.0, 8.0)
GAINS = (0.2, 0.25, 1.0 / 3.0, 0.4, 0.5)


def scan(seconds: float, set_check: bool) -> tuple[int, int, int]:
    """(runs, runs that broke the bound, of those never flagged); a line per run."""
    broken = unflagged = runs = 0
    p = P_SET if set_check else P
    initial = initial_tank_j(SUITE, p)
    for k_op, period, gain in itertools.product(OPERATORS_N_PER_M, PERIODS_S, GAINS):
        sc = replace(PUSH, op_stiffness=k_op, ref_period_s=period, sensor_gain_factor=gain,
                     steps=round(seconds * 1000.0))
        t0 = time.perf_counter()
        r = run_loop(SUITE, p, sc)
        low = min(r.audit_margin_j(initial))
        bad = audit_failure(r, initial) != ""
        runs += 1
        broken += bad
        unflagged += bad and r.yielding_hand == 0
        print(f"{k_op:7.0f} N/m  {period:3.0f} s grasps  gain {gain:.3f}  flagged "
              f"{r.yielding_hand}  margin min {low * 1e3:8.2f} mJ  {'BROKEN' if bad else 'ok'}"
              f"  ({time.perf_counter() - t0:.1f} s)", flush=True)
    return runs, broken, unflagged


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--no-set-check", action="store_true",
                    help="the end-of-contact set check off (the default configuration)")
    ap.add_argument("--seconds", type=float, default=6.0, help="virtual seconds per run")
    a = ap.parse_args()
    runs, broken, unflagged = scan(a.seconds, not a.no_set_check)
    print(f"{runs} runs: {broken} broke the bound, {unflagged} of them never flagged")
    return 0


if __name__ == "__main__":
    sys.exit(main())
