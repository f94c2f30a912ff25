"""What the yield credit (``controller.tactile.yield_credit``) does to every grasp: each
operator on each of the grid's objects, with and without link delay, true cells and cells
reading a third, the credit on and off side by side.

    python tests/services/yield_credit_grasps.py [--seconds 60] [--jobs 2] [--only crushable-cylinder]

Lockstep, seed 1.  Per run: the grasps' peak pressures (``teleop grasps``' rule), the last
over the first and the lowest over the first, the hand's tank at the end, what the hand port
paid and what the object kept (the simulator's own audit, never the controller's ledger), the
lowest of paid minus kept over the run (below zero: the tank paid less than the object held at
that moment), and the lowest physical audit margin of the whole loop
(``LockstepResult.audit_margin_j``).  docs/controllers.md ("What a set costs") quotes the figures.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

DELAYS_S = (0.0, 0.002)
GAINS = (1.0, 0.333)


def one_run(operator: str, obj: str, delay_s: float, gain: float, credit: bool,
            seconds: float, extra: tuple[str, ...] = ()) -> dict[str, object]:
    import numpy as np

    from teleop.analysis.sweep_objects import with_object
    from teleop.config import load_config
    from tests.services.lockstep_grasps import run_grasps

    cfg = with_object(load_config(None, [
        f"master.virtual.style={operator}", f"links.controller_hand.delay_s={delay_s}",
        f"links.master_controller.delay_s={delay_s}", f"hand.sim.tactile_gain={gain}",
        f"controller.tactile.yield_credit={'true' if credit else 'false'}", *extra]), obj)
    r, g = run_grasps(cfg, seconds)
    peaks = [float(s.peak_pressure) for s in g.grasps]
    paid = np.asarray(r.hand_port_out_j) - np.asarray(r.hand_port_in_j)
    kept = (np.asarray(r.audit_environment_delivered_j)
            - np.asarray(r.audit_environment_taken_j))
    return {"operator": operator, "object": obj, "delay_s": delay_s, "gain": gain,
            "credit": credit, "peaks": peaks, "tank_j": float(r.hand_tank_j[-1]),
            "paid_j": float(paid[-1]), "kept_j": float(kept[-1]),
            "min_paid_minus_kept_j": float(np.min(paid - kept)),
            "min_audit_margin_j": float(np.min(r.audit_margin_j))}


def line(d: dict[str, object]) -> str:
    peaks = d["peaks"]
    assert isinstance(peaks, list)
    first = peaks[0] if peaks else float("nan")
    low = min(peaks) / first if peaks and first > 0 else float("nan")
    last = peaks[-1] / first if peaks and first > 0 else float("nan")
    later = peaks[4:]
    best_early = max(peaks[1:4]) if len(peaks) > 1 else float("nan")
    weakest = min(later) / best_early if later and best_early > 0 else float("nan")
    return (f"{d['operator']:7s} {d['object']:18s} {1e3 * float(d['delay_s']):3.0f} ms "  # type: ignore[arg-type]
            f"cells x{d['gain']} credit {'on ' if d['credit'] else 'off'}: {len(peaks):2d} grasps, "
            f"first {first:6.0f}, lowest {low:4.2f}, last {last:4.2f}, weakest of 5- over best of "
            f"2-4 {weakest:4.2f}; tank {d['tank_j']:5.2f} J; "
            f"paid {d['paid_j']:6.3f} J kept {d['kept_j']:6.3f} J, lowest paid-kept "
            f"{1e3 * float(d['min_paid_minus_kept_j']):7.1f} mJ, "  # type: ignore[arg-type]
            f"lowest audit margin {d['min_audit_margin_j']:.3f} J")


def main() -> int:
    from teleop.analysis.sweep_objects import OBJECTS, OPERATORS

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only", choices=tuple(OBJECTS), default=None, help="one object")
    ap.add_argument("--delays", type=float, nargs="+", default=DELAYS_S,
                    help="one-way delays of both links, s")
    ap.add_argument("--operators", nargs="+", choices=OPERATORS, default=OPERATORS)
    ap.add_argument("--gains", type=float, nargs="+", default=GAINS,
                    help="the cells' gains (hand.sim.tactile_gain)")
    ap.add_argument("--set", dest="extra", action="append", default=[],
                    help="a further config override for every run (KEY=VALUE)")
    a = ap.parse_args()
    objects = (a.only,) if a.only else tuple(OBJECTS)
    cases = [(op, ob, d, g, c) for ob in objects for op in a.operators for d in a.delays
             for g in a.gains for c in (False, True)]
    with ProcessPoolExecutor(a.jobs, mp_context=mp.get_context("spawn")) as ex:
        futures = [ex.submit(one_run, *case, a.seconds, tuple(a.extra)) for case in cases]
        for f in futures:
            print(line(f.result()), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
