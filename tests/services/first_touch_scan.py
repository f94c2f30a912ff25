"""Per-grasp peak pressures of the first touch under delay, lockstep (not a test: the scan
behind docs/controllers.md's touch-cap table).

    python tests/services/first_touch_scan.py 30 1.0 links.master_controller.loss=0.2 \
        links.controller_hand.loss=0.2

Every operator (soft, relaxed, hard) on the soft cylinder, the stiff cylinder and the block,
with the given one-way delay on both links; prints each run's grasp peaks, the weakest over
the first by peak pressure, closure and felt force, and the smallest margin of the physical
energy audit.  ``SCAN_STYLES=soft`` (comma-separated) scans only those operators.
"""

from __future__ import annotations

import os
import sys

import numpy as np

from teleop.analysis.sweep_objects import with_object
from teleop.config import load_config
from tests.services.lockstep_grasps import run_grasps


def main(argv: list[str]) -> None:
    secs, delay, extra = float(argv[0]), argv[1], argv[2:]
    styles = os.environ.get("SCAN_STYLES", "soft,relaxed,hard").split(",")
    for style in styles:
        for obj in ("soft-cylinder", "stiff-cylinder", "block"):
            cfg = with_object(load_config(None, [
                f"master.virtual.style={style}", f"links.master_controller.delay_s={delay}",
                f"links.controller_hand.delay_s={delay}", *extra]), obj)
            r, g = run_grasps(cfg, secs)
            peaks = [int(s.peak_pressure) for s in g.grasps]
            closures = [round(s.closure_rad, 3) for s in g.grasps]
            felt = min(s.felt_ratio for s in g.grasps)
            print(f"{style:8} {obj:15} {delay} s  peaks {peaks}  weakest/first "
                  f"{g.min_pressure_ratio:.2f}  closures {closures} weakest/first "
                  f"{g.min_closure_ratio:.2f}  felt {felt:.2f}  audit margin "
                  f"{np.nanmin(r.audit_margin_j):.4f} J", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:] or ["30", "1.0"])
