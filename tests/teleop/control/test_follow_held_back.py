"""A starved hand is felt as what it presses (``controller.contact_model.follow_held_back``).

The master renders a finger's model ``k (s - c)`` at the set-point ``s`` its trigger asks for;
the hand presses ``k (y - c)`` at the set-point ``y`` it applies, which its tank may hold back.
The hand keeps a shadow set-point (the command slewed as its layer slews it, never held back)
and sends the contact angle moved out by the shadow minus the applied set-point, so the force
rendered at the shadow is the model's force at the applied set-point."""

from __future__ import annotations

from dataclasses import replace

import pytest

from teleop.config.control import ControllerConfig
from teleop.control import two_layer, two_layer_hand
from teleop.control.contact_model import FingerModel, model_wire
from teleop.control.interface import control_params
from teleop.control.two_layer_hand import HandPortState
from teleop.messages import FingerState, HandCommand, HandMode, Header
from tests.mutants import fails

P = control_params(ControllerConfig())
DT = 0.025


def _finger(x: float, pressure: float = 0.0) -> FingerState:
    return FingerState(proximal_rad=x, distal_rad=0.0, motor_angle_rad=x, load_units=0.0,
                       pressure=(pressure,) + (0.0,) * 8,
                       contact=(pressure > 0.0,) + (False,) * 8)


def _command(y: float) -> HandCommand:
    return HandCommand(header=Header(seq=1, t_s=0.0, energy_total_j=0.0),
                       finger_setpoint_rad=(y, y, y), preshape_rad=0.0, mode=HandMode.POSITION,
                       hand_echo_t_s=1e9)  # the controller has seen every touch: no touch cap


def test_the_wire_moves_only_a_valid_model_and_only_outwards() -> None:
    ms = (FingerModel(contact_rad=0.4, stiffness=900.0),
          FingerModel(contact_rad=0.5, stiffness=700.0), FingerModel())
    assert model_wire(ms, (0.25, -0.1, 0.3)) == (0.65, 900.0, 0.5, 700.0, 0.0, 0.0)
    assert model_wire(ms, (0.0, 0.0, 0.0)) == model_wire(ms) == (0.4, 900.0, 0.5, 700.0, 0.0,
                                                                  0.0)


@pytest.mark.parametrize("port", ["object", "servo"])
def test_a_hand_never_held_back_sends_its_model_bit_for_bit(port: str) -> None:
    """With a full tank the shadow is the applied set-point to the last float (the same slew,
    the same floats), so the wire carries the estimated model unmoved."""
    p = replace(P, hand_port=port)
    s = replace(two_layer.init_hand(p),
                models=(FingerModel(contact_rad=0.3, stiffness=800.0),) * 3)
    for k in range(60):
        y = min(0.02 * k, 0.9)
        x = max(y - 0.05, 0.0)  # the motor lags the ramp
        s, out = two_layer.step_hand(s, p, (_finger(x),) * 3, _command(y), DT, t_s=k * DT)
        assert not out.limited
        if k > 0:
            assert s.shadow_rad == out.setpoint_rad
            assert out.contact_model == model_wire(s.models)


def _starved(follow: bool, port: str) -> tuple[tuple[float, ...], tuple[float, ...],
                                                tuple[float, ...], tuple[float, ...]]:
    """A hand whose tank is nearly empty, asked to close on an object it touches: (applied
    set-points, shadow, the models as estimated, the wire)."""
    cm = replace(P.contact_model, follow_held_back=follow)
    p = replace(P, hand_port=port, contact_model=cm, initial_j=0.02, min_j=0.01,
                transfer_fraction=0.0)
    s = replace(two_layer.init_hand(p),
                models=(FingerModel(contact_rad=0.3, stiffness=800.0, touching=True),) * 3)
    out = None
    for k in range(40):
        s, out = two_layer.step_hand(s, p, (_finger(0.32, 60.0),) * 3, _command(1.2), DT,
                                     t_s=k * DT)
    assert out is not None and out.limited
    assert s.models is not None
    wire_models = model_wire(s.models)
    shadow = s.shadow_rad if s.shadow_rad is not None else out.setpoint_desired_rad
    return out.setpoint_rad, shadow, wire_models, out.contact_model


@pytest.mark.parametrize("port", ["object", "servo"])
def test_a_starved_hand_is_rendered_at_what_it_presses(port: str) -> None:
    """Held back by its tank, the hand's shadow runs on towards the command; the force the
    master renders at the shadow, ``k (s - c')``, is the model's force at the applied
    set-point, ``k (y - c)``."""
    y, shadow, est, wire = _starved(True, port)
    for i in range(3):
        c, k, c_wire = est[2 * i], est[2 * i + 1], wire[2 * i]
        assert k > 0.0 and wire[2 * i + 1] == k
        assert shadow[i] - y[i] > 0.3  # held back well short of what the command asks
        assert k * (shadow[i] - c_wire) == pytest.approx(k * max(y[i] - c, 0.0), abs=1e-6)


@pytest.mark.parametrize("port", ["object", "servo"])
def test_without_it_a_starved_hand_is_rendered_as_a_firm_grasp(port: str) -> None:
    """The mutant kept as a test (``follow_held_back`` off): the estimated model goes out
    unmoved and renders the shadow's depth, several times what the hand presses."""
    y, shadow, est, wire = _starved(False, port)
    assert wire == est
    for i in range(3):
        c, k = est[2 * i], est[2 * i + 1]
        assert k * (shadow[i] - c) > 2.0 * k * max(y[i] - c, 0.0)


def test_a_shadow_taken_from_the_applied_set_point_is_caught(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The mutant kept as a test: the shadow slewed from the held-back set-point each sample
    (what "the set-point asked for" means inside the layer) runs at most one slew step ahead,
    so the model moves out by ~0.1 rad and the starved hand is still felt firm."""
    built = two_layer_hand.shadow_setpoints

    def from_applied(s: HandPortState, *a: object) -> tuple[float, float, float]:
        return built(replace(s, shadow_rad=None), *a)  # type: ignore[arg-type]

    monkeypatch.setattr(two_layer_hand, "shadow_setpoints", from_applied)
    for port in ("object", "servo"):
        assert fails(lambda port=port: test_a_starved_hand_is_rendered_at_what_it_presses(port))
