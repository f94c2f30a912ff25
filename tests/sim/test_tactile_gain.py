"""``hand.sim.tactile_gain``: mis-calibrated tactile cells scale the pressure readings, once,
in both engines, and never the physics (a sensor reading low does not soften the object);
``hand.sim.distal_tactile_gain`` the distal pad's four cells alone."""

from __future__ import annotations

import pytest

from sim.sim_hand import SimHand
from teleop.config import load_config
from teleop.messages import HandCommand, HandMode, Header


def _grasp(engine: str, gain: float, *overrides: str) -> SimHand:
    cfg = load_config(None, [f"hand.sim.engine={engine}", f"hand.sim.tactile_gain={gain}",
                             "hand.sim.noise=false", *overrides])
    hand = SimHand(cfg.hand, seed=0)
    hand.start()
    hand.apply(HandCommand(Header(1, 0.0, 0.0), (1.5, 1.4, 1.3), 0.3, HandMode.POSITION,
                           (0.0, 0.0, 0.0)))
    for k in range(1, 81):  # 2 s at 40 Hz: into the default cylinder
        hand.read(k / 40.0)
    return hand


@pytest.mark.parametrize("engine", ["compiled", "python"])
def test_cells_read_a_third_of_the_nominal_and_the_physics_is_unchanged(engine: str) -> None:
    true, low = _grasp(engine, 1.0), _grasp(engine, 0.333)
    assert true.state == low.state  # the same physics, bit for bit
    assert true.port_audit_j() == low.port_audit_j()
    for ft, fl in zip(true.truth().fingers, low.truth().fingers, strict=True):
        assert max(ft.pressure) > 100.0  # a firm grasp: the cells are loaded
        for a, b in zip(ft.pressure, fl.pressure, strict=True):
            assert b == pytest.approx(0.333 * a, rel=1e-12, abs=1e-12)



def test_the_distal_gain_scales_the_distal_pads_readings_alone() -> None:
    true = _grasp("compiled", 1.0)
    low = _grasp("compiled", 1.0, "hand.sim.distal_tactile_gain=0.25")
    assert true.state == low.state
    t_read, l_read = true.read(2.025), low.read(2.025)
    n = len(true.params.finger.proximal_sensor_x_m)
    for ft, fl in zip(t_read.fingers, l_read.fingers, strict=True):
        assert max(ft.pressure[n:]) > 50.0  # the distal pad is loaded
        assert fl.pressure[:n] == ft.pressure[:n]
        for a, b in zip(ft.pressure[n:], fl.pressure[n:], strict=True):
            assert b == pytest.approx(0.25 * a, rel=1e-12, abs=1e-12)
