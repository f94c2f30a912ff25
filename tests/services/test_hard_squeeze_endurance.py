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

Strict: when a change makes these grasps hold, this test fails until the marker goes, and
the README's energy-budget paragraph is corrected with it.
"""

from __future__ import annotations

import pytest

from services.lockstep import run_lockstep
from teleop.analysis.energy_budget import grasp_budget
from teleop.config import load_config

pytestmark = pytest.mark.slow


@pytest.mark.xfail(strict=True, reason="known defect: the hand's pad-work estimate reads a "
                   "hard squeeze of the block 6-7x both ways and keeps ~0.6 J a squeeze (0.41 "
                   "J a grasp charged, 1.4 mJ net taken); the stores run out after ~18 grasps "
                   "(docs/controllers.md, 'Hard squeezes over ten minutes')")
def test_the_hard_operators_grasps_on_the_block_hold_for_two_minutes() -> None:
    cfg = load_config(None, ["master.virtual.style=hard", "hand.sim.object.kind=block"])
    r = run_lockstep(cfg, 120.0, seed=1)
    peaks = [b.peak_pressure for b in grasp_budget(r, cfg.master.virtual.cycle_s)]
    assert len(peaks) >= 25
    assert peaks[0] > 4000  # the squeeze reached the servo's limit
    weakest = min(peaks)
    assert weakest >= 0.9 * peaks[0], f"weakest grasp {weakest:.0f} of the first {peaks[0]:.0f}"
