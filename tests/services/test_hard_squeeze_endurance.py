"""A known defect kept as a strict xfail: the hard operator's squeezes on the block outlast
the stores.

Measured 2026-11-28 (`teleop budget --seconds 600 --set master.virtual.style=hard --set
hand.sim.object.kind=block`): every grasp reaches 4,455-4,465 until grasp 18, then the peak
falls grasp by grasp (3,549 at grasp 26, 2 % of the first by 7 minutes). The hand's ledger
charges 0.4-0.5 J a grasp for 4-5 mJ of physical work on the object; the trigger and the tank
level controller do not supply that, so the hand's tank falls under what a full squeeze must
reserve. Where the charge comes from (docs/controllers.md, "Hard squeezes over ten
minutes"; ``tests/teleop/control/pad_work_phases.py``): the distal pads press the block's face
near their tips at 80-87 N, the estimate reads their motion along the pad's own normal
(``r dtheta``), ten to fifteen times the motion into the face, in both directions, and its
safe-side rule (the larger force and lever in, the smaller out) keeps 0.6 J per squeeze. The
relaxed operator (the default) on the same block holds 1,200-1,203 over the same 10
minutes.

What is checked, in CI's time: the first sign of it, the hand's tank holding the set-points
back through a squeeze (the `hand starved` alarm: a spell of 1.5 s; healthy runs are never
held back over 0.05 s at a time, tests/services/starve_spells.py). In lockstep it first fires
at 38.9 s, while the grasps are still full; over 50 s it fires three times (with tanks of
100 J the same run is never held back, so the check can pass). (Until 2026-11-29 the
test ran 120 s and asked every grasp to keep 0.9 of the first's peak, the weakest at 0.80:
52 s of CI, where this takes ~20 s; `teleop budget --seconds 120 --set
master.virtual.style=hard --set hand.sim.object.kind=block` shows the grasps.)

Strict: when a change makes these squeezes affordable, this test fails until the marker goes,
and the README's energy-budget paragraph is corrected with it.
"""

from __future__ import annotations

import pytest

from services.lockstep import run_lockstep
from teleop.config import load_config

pytestmark = pytest.mark.slow


@pytest.mark.xfail(strict=True, reason="known defect: the hand's pad-work estimate reads a "
                   "hard squeeze of the block 6-7x both ways and keeps ~0.6 J a squeeze (0.41 "
                   "J a grasp charged, 1.4 mJ net taken); the stores run out after ~18 grasps "
                   "(docs/controllers.md, 'Hard squeezes over ten minutes')")
def test_the_hard_operators_squeezes_on_the_block_never_starve_the_hand() -> None:
    cfg = load_config(None, ["master.virtual.style=hard", "hand.sim.object.kind=block"])
    seen = {"spells": 0}

    def hook(_t: float, ctx: object) -> None:
        hand = getattr(ctx, "hand")  # noqa: B009
        seen["spells"] = hand.starve.spells

    r = run_lockstep(cfg, 50.0, seed=1, hook=hook)
    assert float(r.pressure.max()) > 4000  # the squeezes reached the servo's limit
    assert seen["spells"] == 0, f"the hand was starved {seen['spells']} times in 50 s"
