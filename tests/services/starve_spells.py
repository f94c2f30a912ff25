"""How long the hand's tank holds the set-points back at a time: the measurement behind the
"hand starved" alarm's threshold (``safety.starved_alarm_s``, :mod:`services.starve_alarm`).

    python tests/services/starve_spells.py [--seconds 60] [--jobs 2] [--only block]

Lockstep, seed 1: every operator on every grid object, cells reading a third under the
relaxed and the hard operator on the stiff cylinder, the relaxed operator at 0.2 s and 1 s on
both links on the stiff cylinder, the block and the crushable cylinder, and two long runs
(the hard operator on the block for 120 s, the relaxed one on the crushable cylinder for
360 s).  A spell is a run of hand samples (40 Hz) on which the passivity layer held the
set-points back (the hand's ``limit_count`` rising), found as ``teleop grasps`` finds a
store's empty spells.  Per run: the
number of spells, the four longest (start s, length s) and when the alarm's own step at the
configured threshold would first have fired.  docs/controllers.md ("hand starved") quotes the
figures.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

OBJECTS = ("free-air", "soft-cylinder", "stiff-cylinder", "block", "crushable-cylinder")
OPERATORS = ("soft", "relaxed", "hard")
HAND_DT_S = 0.025


def one_run(operator: str, obj: str, gain: float, seconds: float,
            extra: tuple[str, ...]) -> dict[str, object]:
    import numpy as np

    from services.lockstep import run_lockstep
    from services.starve_alarm import QUIET, starve_step
    from teleop.analysis.recorded_run import _spans
    from teleop.analysis.sweep_objects import with_object
    from teleop.config import load_config

    cfg = with_object(load_config(None, [f"master.virtual.style={operator}",
                                         f"hand.sim.tactile_gain={gain}", *extra]), obj)
    r = run_lockstep(cfg, seconds, seed=1)
    count, t = np.asarray(r.hand_limited_count), np.asarray(r.t_s)
    # the hand's samples (its 40 Hz ticks): limited when its count rose since the one before
    at = np.searchsorted(t, np.arange(0.0, t[-1] + 1e-9, HAND_DT_S) - 1e-9)
    hand_t = t[at]
    limited = np.diff(count[at], prepend=count[0]) > 0
    spells = _spans(hand_t, limited)  # ``teleop grasps``' stretches, one hand sample each
    alarm, first = QUIET, None
    for tk, lim in zip(hand_t, limited, strict=True):  # the alarm's own step, as configured
        alarm, fire = starve_step(alarm, bool(lim), float(tk), cfg.safety.starved_alarm_s)
        if fire and first is None:
            first = round(float(tk), 2)
    longest = sorted(spells, key=lambda s: -s[1])[:4]
    return {"operator": operator, "object": obj, "tactile_gain": gain, "seconds": seconds,
            "extra": " ".join(extra), "spells": len(spells),
            "longest": [(round(a, 1), round(b, 2)) for a, b in longest],
            "first_alarm_s": first}


def cases(seconds: float) -> list[tuple[str, str, float, float, tuple[str, ...]]]:
    out = [(op, obj, 1.0, seconds, ()) for obj in OBJECTS for op in OPERATORS]
    out += [(op, "stiff-cylinder", 0.333, seconds, ()) for op in ("relaxed", "hard")]
    for d in (0.2, 1.0):
        links = (f"links.master_controller.delay_s={d}", f"links.controller_hand.delay_s={d}")
        out += [("relaxed", obj, 1.0, seconds, links)
                for obj in ("stiff-cylinder", "block", "crushable-cylinder")]
    out += [("hard", "block", 1.0, 120.0, ()), ("relaxed", "crushable-cylinder", 1.0, 360.0, ())]
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only", default=None, help="one grid object")
    a = ap.parse_args(argv)
    todo = [c for c in cases(a.seconds) if a.only is None or c[1] == a.only]
    with ProcessPoolExecutor(a.jobs, mp_context=mp.get_context("spawn")) as ex:
        for res in ex.map(one_run, *zip(*todo, strict=True)):
            print(f"{res['operator']:8s} {res['object']:19s} cells x{res['tactile_gain']} "
                  f"{res['seconds']:.0f} s {res['extra']}: {res['spells']} spells, longest "
                  f"{res['longest']}, first alarm {res['first_alarm_s']}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
