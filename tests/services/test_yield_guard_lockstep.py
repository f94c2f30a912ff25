"""The yielding-contact guard on the simulated hand, lockstep, judged by the physical audit.

A cylinder that crushes at 5 N under each pad (``hand.sim.object.yield_force_n``) and tactile
cells reading a third of the true force (``hand.sim.tactile_gain``): the first grasp dents the
object for good, so every joule the pads put in stays there.  The hand port's bound is that
the object receives no more than the hand's tank has paid (its ledger's net charge); the
object-port work comes from the simulator's own audit, never from the controller.
"""

from __future__ import annotations

import numpy as np
import pytest

from services.lockstep import run_lockstep
from teleop.config import load_config

CRUSH = ("hand.sim.object.yield_force_n=5", "hand.sim.tactile_gain=0.333")


def first_grasp(*overrides: str) -> tuple[float, float, int]:
    """(object net work J, hand ledger net charge J, most fingers flagged yielding) over the
    first grasp of the default script (5 s)."""
    flagged = [0]

    def hook(_t: float, ctx: object) -> None:
        flagged[0] = max(flagged[0], getattr(getattr(ctx, "hand", None), "_yielding", 0))

    r = run_lockstep(load_config(None, list(overrides)), 5.0, seed=1, hook=hook)
    assert r.has_audit
    obj = float(r.audit_environment_delivered_j[-1] - r.audit_environment_taken_j[-1])
    paid = float(r.hand_port_out_j[-1] - r.hand_port_in_j[-1])
    return obj, paid, flagged[0]


@pytest.mark.slow
def test_cells_reading_low_on_a_crushing_object_raise_the_alarm_and_the_tank_pays() -> None:
    obj, paid, flagged = first_grasp(*CRUSH)
    assert obj > 0.1  # the pads did crush it
    assert flagged >= 1
    assert paid >= obj


@pytest.mark.slow
def test_without_the_guard_the_tank_pays_less_than_the_object_took() -> None:
    """The mutant kept as a test: the guard off, the same grasp is charged a fraction of
    the work the object really took (the bound broken, silently)."""
    obj, paid, flagged = first_grasp(*CRUSH, "controller.tactile.yield_stiffness_ratio=0")
    assert flagged == 0
    assert np.isfinite(paid) and paid < 0.5 * obj
