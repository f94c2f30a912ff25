"""The first grasp of the yield-guard lockstep tests (a top-level function, so a test module can
run its grasps on the tests' lockstep pool, ``tests/job_pool.py``)."""

from __future__ import annotations

from services.lockstep import run_lockstep
from teleop.config import load_config


def first_grasp(*overrides: str) -> tuple[float, float, int, int, int]:
    """(object net work J, hand ledger net charge J, most fingers flagged yielding, most
    flagged stalled on an unseen contact, most flagged with cells reading low) over the first
    grasp of the default script (5 s)."""
    flagged = [0, 0, 0]

    def hook(_t: float, ctx: object) -> None:
        hand = getattr(ctx, "hand", None)
        flagged[0] = max(flagged[0], getattr(hand, "_yielding", 0))
        flagged[1] = max(flagged[1], getattr(hand, "_unseen", 0))
        flagged[2] = max(flagged[2], getattr(hand, "_cells_low", 0))

    r = run_lockstep(load_config(None, list(overrides)), 5.0, seed=1, hook=hook)
    assert r.has_audit
    obj = float(r.audit_environment_delivered_j[-1] - r.audit_environment_taken_j[-1])
    paid = float(r.hand_port_out_j[-1] - r.hand_port_in_j[-1])
    return obj, paid, flagged[0], flagged[1], flagged[2]
