"""The registry matches the config choices; every suite honours the shared interface."""

from __future__ import annotations

import dataclasses
import math
import typing

import pytest

from teleop.config.control import ControllerConfig
from teleop.control.energy_channel import energy_balance
from teleop.control.interface import ControllerOutput, HandOutput, MasterOutput, master_message
from teleop.control.registry import CONTROLLERS, controller_suite
from teleop.errors import ConfigError
from teleop.messages import FingerState, ForceCommand, HandMode, Header


def test_registry_keys_are_the_config_choices() -> None:
    field = {f.name: f for f in dataclasses.fields(ControllerConfig)}["kind"]
    assert set(field.metadata["choices"]) == set(CONTROLLERS)
    with pytest.raises(ConfigError, match="controller.kind"):
        controller_suite(dataclasses.replace(ControllerConfig(), kind="magic"))


@pytest.mark.parametrize("kind", sorted(CONTROLLERS))
def test_one_cycle_of_every_role(kind: str) -> None:
    suite, p = controller_suite(ControllerConfig(kind=kind))
    assert suite.name == kind
    ms, cs, hs = suite.init_master(p), suite.init_controller(p), suite.init_hand(p)
    ms, mo = suite.step_master(ms, p, 0.01, None, 1e-3)
    assert isinstance(mo, MasterOutput) and mo.force_n == 0.0
    msg = master_message(mo, seq=1, t_s=0.0)
    assert msg.grip_position_m == 0.01
    cs, co = suite.step_controller(cs, p, msg, None, 0.0, 1e-3)
    assert isinstance(co, ControllerOutput)
    assert co.hand_command.mode == HandMode.POSITION
    assert co.hand_command.finger_setpoint_rad == pytest.approx((1.2, 1.2, 1.2))
    assert co.force_command.header.seq == co.hand_command.header.seq == 1
    f = FingerState(0.0, 0.0, 0.0, 0.0, (0.0,) * 9, (False,) * 9)
    hs, ho = suite.step_hand(hs, p, (f, f, f), co.hand_command, 0.025)
    assert isinstance(ho, HandOutput)
    assert all(math.isfinite(v) for v in ho.setpoint_rad)
    assert energy_balance((mo.ledger, co.ledger, ho.ledger)).ok == suite.passive
    hints = typing.get_type_hints(MasterOutput)
    assert hints["force_n"] is float


def test_two_layer_master_never_shows_force_it_cannot_pay() -> None:
    suite, p = controller_suite(ControllerConfig(kind="two-layer"))
    p = dataclasses.replace(p, initial_j=0.0)
    st = suite.init_master(p)
    cmd = ForceCommand(Header(seq=1, t_s=0.0, energy_total_j=0.0), force_n=-8.0)
    # the operator opens the trigger while a pulling force is asked for: the device would
    # deliver energy, the empty tank cannot pay, so no force
    q = 0.02
    for _ in range(50):
        q -= 2e-5
        st, out = suite.step_master(st, p, q, cmd, 1e-3)
        assert out.force_n == 0.0 or out.force_n * out.grip_velocity_m_s >= 0.0
        assert out.ledger.tank_j >= 0.0
    assert out.limited


def test_nan_inputs_do_not_propagate() -> None:
    for kind in CONTROLLERS:
        suite, p = controller_suite(ControllerConfig(kind=kind))
        st = suite.init_master(p)
        cmd = ForceCommand(Header(seq=1, t_s=0.0, energy_total_j=math.nan), force_n=math.nan)
        st, out = suite.step_master(st, p, math.nan, cmd, 1e-3)
        assert out.force_n == 0.0 and math.isfinite(out.grip_position_m)
        assert energy_balance((out.ledger,)).ok or kind == "direct"
