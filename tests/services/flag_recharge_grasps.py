"""What the yield guard's flag re-charge costs a grasp: every grasp's peak pressure with and
without it, on the crushable cylinder.

    python tests/services/flag_recharge_grasps.py

Lockstep, seed 1, the grid's ``crushable-cylinder``: the default (relaxed) operator for 60 s
with true cells, the hard operator for 120 s with true cells, and the default operator for
60 s with cells reading a third (``hand.sim.tactile_gain=0.333``); each run once as built and
once with :func:`teleop.control.yield_guard.flag_recharges_j` replaced by zeros on the hand side
(the guard as before the re-charge).  Per run: the grasps' peak pressures (``teleop
grasps``' rule, :func:`teleop.analysis.sweep_endurance.grasps_from_columns`), their range, and
the hand's tank at the end.  docs/controllers.md quotes the figures.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from teleop.analysis.sweep_objects import with_object  # noqa: E402
from teleop.config import load_config  # noqa: E402
from teleop.control import two_layer_hand  # noqa: E402
from tests.services.lockstep_grasps import run_grasps  # noqa: E402

#: the yield credit (on by default since 2026-11-29) gives the re-charge back once the gain
#: cross-check has measured the cells: off here, as when these figures were taken
#: (``tests/services/yield_credit_grasps.py`` measures it)
CREDIT_OFF = "controller.tactile.yield_credit=false"
#: (label, seconds, overrides)
RUNS = (("default operator, true cells", 60.0, ()),
        ("hard operator, true cells", 120.0, ("master.virtual.style=hard",)),
        ("default operator, cells reading a third", 60.0, ("hand.sim.tactile_gain=0.333",)))


def main() -> int:
    built = two_layer_hand.flag_recharges_j
    for label, seconds, overrides in RUNS:
        cfg = with_object(load_config(None, [*overrides, CREDIT_OFF]), "crushable-cylinder")
        for recharge in (True, False):
            two_layer_hand.flag_recharges_j = (  # type: ignore[assignment]
                built if recharge else (lambda *_a: (0.0, 0.0, 0.0)))
            r, g = run_grasps(cfg, seconds)
            peaks = [round(s.peak_pressure) for s in g.grasps]
            span = f"{min(peaks)}-{max(peaks)}" if peaks else "-"
            print(f"{label}, {seconds:.0f} s, re-charge {'on ' if recharge else 'off'}: "
                  f"{len(peaks)} grasps, peak pressure {span} ({peaks}), hand tank at the "
                  f"end {r.hand_tank_j[-1]:.1f} J", flush=True)
    two_layer_hand.flag_recharges_j = built  # type: ignore[assignment]
    return 0


if __name__ == "__main__":
    sys.exit(main())
