"""The sweep's signal adapter: which runs can have their holds judged."""

from __future__ import annotations

import numpy as np

from teleop.analysis.stability import classify_run
from teleop.analysis.sweep_signals import hold_segments_s, signals_from_columns
from teleop.config import load_config


def _cols(n: int) -> dict[str, np.ndarray]:
    t = np.arange(n) * 1e-3
    g = 0.01 * (1 - np.cos(2 * np.pi * t / 4.5))  # the operator's grasps, nothing else
    z = np.zeros(n)
    return {"t_s": t, "trigger_position_m": g, "setpoint_rad": np.column_stack([g] * 3),
            "motor_angle_rad": np.column_stack([100 * g] * 3), "displayed_force_n": 200 * g,
            "pressure": np.zeros((n, 27)), "master_port_out_j": z, "hand_port_out_j": z,
            "master_port_in_j": z, "hand_port_in_j": z}


def test_holds_shorter_than_the_round_trip_are_judged_for_growth_only() -> None:
    slow = load_config(None, ["links.master_controller.delay_s=1.0", "master.virtual.hold_s=2"])
    assert hold_segments_s(slow, 40.0) == ()
    s = signals_from_columns(_cols(40_000), slow, 0.0)
    assert s.growth_only
    m = classify_run(s)
    assert m.stable and m.judged == "growth only"
    fast = load_config(None, ["links.master_controller.delay_s=0.2"])
    s = signals_from_columns(_cols(40_000), fast, 0.0)
    assert hold_segments_s(fast, 40.0) and not s.growth_only
    assert classify_run(s).judged == "holds"


def test_a_single_grasp_is_never_growth_only() -> None:
    one = load_config(None, ["links.master_controller.delay_s=1.0", "master.virtual.repeat=false"])
    assert not signals_from_columns(_cols(20_000), one, 0.0).growth_only
