"""The hand service picks the servo-spring passivity layer on a backend without tactile cells
(the environment-port layer would see no contact there and charge nothing)."""

from __future__ import annotations

from services.hand_service import hand_control_params
from teleop.config import load_config


def test_the_simulated_hand_uses_the_object_port() -> None:
    p, note = hand_control_params(load_config())
    assert p.hand_port == "object" and note == ""


def test_a_hand_without_tactile_cells_falls_back_to_the_servo_layer() -> None:
    p, note = hand_control_params(load_config(None, ["hand.backend=dynamixel"]))
    assert p.hand_port == "servo"
    assert "no tactile sensors" in note and "hand_port=servo" in note
    assert "wear the grasps down" in note  # the known limit is said where it starts


def test_an_explicit_servo_layer_is_kept_without_a_note() -> None:
    p, note = hand_control_params(load_config(None, ["controller.ports.hand_port=servo"]))
    assert p.hand_port == "servo" and note == ""
