"""What the operator feels of a starved hand: every grasp with the rendered model following the
held-back hand (``controller.contact_model.follow_held_back``, the default) and without it,
side by side.

    python tests/services/follow_held_back_grasps.py [--jobs 2] [--scale 1.0] [--only block]

Lockstep, seed 1: the runs in which the hand's tank holds the set-points back for seconds
(the hard operator on the block and on the stiff cylinder over ten minutes, the relaxed
operator on the crushable cylinder over six, cells reading a third under the hard operator)
and two healthy ones (the relaxed operator on the stiff cylinder, and on the block at 1 s).
Per run: the grasps (``teleop grasps``' rule), the weakest peak pressure over the first, the
grasps felt but not held (:attr:`teleop.analysis.grasps.GraspSeries.felt_not_held`, with the
controller's measured-force command), the felt force of the weakest grasp beside the force
its pressure asked for, the lowest physical audit margin of the loop and a digest of the
pressures and displayed forces (equal digests: the same run to the last float).
``--scale`` multiplies every run's length.  docs/controllers.md quotes the figures.
"""

from __future__ import annotations

import argparse
import hashlib
import multiprocessing as mp
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

#: (label, operator, object, seconds, extra overrides)
RUNS: tuple[tuple[str, str, str, float, tuple[str, ...]], ...] = (
    ("hard, block", "hard", "block", 600.0, ()),
    ("hard, stiff cylinder", "hard", "stiff-cylinder", 600.0, ()),
    ("relaxed, crushable cylinder", "relaxed", "crushable-cylinder", 360.0, ()),
    ("hard, stiff cylinder, cells a third", "hard", "stiff-cylinder", 60.0,
     ("hand.sim.tactile_gain=0.333",)),
    ("relaxed, stiff cylinder (healthy)", "relaxed", "stiff-cylinder", 60.0, ()),
    ("relaxed, block, 1 s (healthy)", "relaxed", "block", 60.0,
     ("links.master_controller.delay_s=1.0", "links.controller_hand.delay_s=1.0")),
)


def one_run(label: str, operator: str, obj: str, seconds: float, extra: tuple[str, ...],
            follow: bool) -> dict[str, object]:
    import numpy as np

    from services.lockstep import run_lockstep
    from teleop.analysis.grasps import curl_grasps, grasp_threshold_m
    from teleop.analysis.sweep_objects import with_object
    from teleop.config import load_config

    cfg = with_object(load_config(None, [
        f"master.virtual.style={operator}", *extra,
        f"controller.contact_model.follow_held_back={'true' if follow else 'false'}"]), obj)
    r = run_lockstep(cfg, seconds, seed=1)
    g = curl_grasps(r.t_s, r.trigger_position_m, r.pressure, r.proximal_rad, r.distal_rad,
                    r.displayed_force_n, grasp_threshold_m(cfg),
                    measured_force_n=r.commanded_force_n)
    weak = g.weakest
    digest = hashlib.md5(np.ascontiguousarray(r.pressure).tobytes()
                         + np.ascontiguousarray(r.displayed_force_n).tobytes()).hexdigest()
    return {"label": label, "follow": follow, "grasps": len(g.grasps),
            "weakest_ratio": g.min_pressure_ratio,
            "weakest": None if weak is None else (weak.index, round(weak.peak_pressure),
                                                  round(weak.felt_force_n, 2),
                                                  round(weak.measured_force_n, 2)),
            "felt_not_held": [x.index for x in g.felt_not_held],
            "audit_margin_j": float(np.min(r.audit_margin_j)),
            "hand_tank_end_j": float(r.hand_tank_j[-1]), "digest": digest[:10]}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--scale", type=float, default=1.0, help="multiplies every run's length")
    ap.add_argument("--only", default=None, help="runs whose label contains this")
    a = ap.parse_args(argv)
    todo = [(lab, op, obj, secs * a.scale, extra, follow)
            for lab, op, obj, secs, extra in RUNS if a.only is None or a.only in lab
            for follow in (True, False)]
    with ProcessPoolExecutor(a.jobs, mp_context=mp.get_context("spawn")) as ex:
        for res in ex.map(one_run, *zip(*todo, strict=True)):
            ratio = res["weakest_ratio"]
            print(f"{res['label']}, follow {'on ' if res['follow'] else 'off'}: "
                  f"{res['grasps']} grasps, weakest {ratio:.2f} (grasp, pressure, felt N, "
                  f"asked N: {res['weakest']}), felt not held {len(res['felt_not_held'])} "
                  f"{res['felt_not_held'][:12]}, audit margin {res['audit_margin_j']:.3f} J, "
                  f"hand tank {res['hand_tank_end_j']:.2f} J, digest {res['digest']}",
                  flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
