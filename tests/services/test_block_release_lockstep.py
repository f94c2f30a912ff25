"""The hard operator's grasps of the block, in lockstep: every release lets the finger go.

Before the block's core was met element by element (``sim.contact.block_core``), the first
hard squeeze at 0 ms drove the distal pads 25 mm into the face and they stayed there: grasp 1
peaked at 15,020, every later one read 9,028, and the pressure between grasps never fell
below 9,021 whatever the trigger did.
"""

from __future__ import annotations

import numpy as np

from teleop.analysis.sweep_objects import with_object
from teleop.config import load_config
from tests.services.lockstep_grasps import run_grasps


def test_the_hard_operator_grasps_the_block_again_and_again() -> None:
    cfg = with_object(load_config(None, ["master.virtual.style=hard"]), "block")
    r, series = run_grasps(cfg, 15.0)
    grasps = series.grasps
    assert len(grasps) >= 3
    peak = r.pressure.max(axis=1)
    for a, b in zip(grasps[:-1], grasps[1:], strict=True):
        between = (r.t_s > a.t_start_s) & (r.t_s < b.t_start_s)
        assert float(peak[between].min()) < 20.0  # released: nothing presses any pad
    ratios = [g.pressure_ratio for g in grasps]
    assert min(ratios) > 0.9 and max(ratios) < 1.1  # every grasp like the first
    assert np.isfinite(r.audit_environment_delivered_j[-1])
    assert r.audit_environment_delivered_j[-1] >= r.audit_environment_taken_j[-1]  # passive
