"""Quick grasps of the crushable cylinder with cells reading low, on the simulated hand.

    python tests/services/quick_grasp_lockstep.py [--no-set-check]

Lockstep, 15 s, seed 1, the hard operator's script shortened (``master.virtual.hold_s`` /
``ramp_s`` / ``release_s``), the grid's ``crushable-cylinder``, cells reading a third or a
fifth (``hand.sim.tactile_gain``).  Per run: the most fingers flagged yielding at once, what
the object kept by the simulator's audit and what the hand's tank paid by its ledger at the
end, the lowest paid-minus-kept over the run, and the loop's audit margin.
``--no-set-check`` runs the same with the yield guard's end-of-contact set check off
(``controller.tactile.yield_set_check``, on by default).
docs/controllers.md quotes the figures.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from services.lockstep import run_lockstep  # noqa: E402
from teleop.analysis.sweep_objects import with_object  # noqa: E402
from teleop.config import load_config  # noqa: E402

#: (hold, close, open) seconds of the operator's script
SCRIPTS = ((0.0, 0.5, 0.3), (0.2, 0.4, 0.3), (0.0, 0.3, 0.2))
GAINS = (0.333, 0.2)


def main() -> int:
    off = "--no-set-check" in sys.argv[1:]
    extra = ["controller.tactile.yield_set_check=false"] if off else []
    for (hold, close, release), gain in ((s, g) for s in SCRIPTS for g in GAINS):
        cfg = with_object(load_config(None, [
            f"hand.sim.tactile_gain={gain}", f"master.virtual.hold_s={hold}",
            f"master.virtual.ramp_s={close}", f"master.virtual.release_s={release}",
            "master.virtual.style=hard", *extra]), "crushable-cylinder")
        most = [0]

        def hook(_t: float, ctx: Any, most: list[int] = most) -> None:
            if ctx.hand:
                most[0] = max(most[0], ctx.hand._yielding)

        r = run_lockstep(cfg, 15.0, seed=1, hook=hook)
        kept = (np.asarray(r.audit_environment_delivered_j)
                - np.asarray(r.audit_environment_taken_j))
        paid = np.asarray(r.hand_port_out_j) - np.asarray(r.hand_port_in_j)
        print(f"hold {hold:.1f} s close {close:.1f} s open {release:.1f} s  gain {gain:.3f}  "
              f"flagged {most[0]}  object kept {kept[-1]:.4f} J  tank paid {paid[-1]:.4f} J  "
              f"lowest paid-kept {np.min(paid - kept) * 1e3:7.1f} mJ  "
              f"audit margin {np.nanmin(r.audit_margin_j):.3f} J", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
