"""Typed messages exchanged by the three services.

Every message carries a sequence number (``seq``), the sender's timestamp (``t_s``, on the
sender's clock), a schema version and the sender's cumulative energy total
(``energy_total_j``): the energy quantum travels as a monotone running total so that a lost,
duplicated or reordered message can only lose energy, never create it.  The receiver adds
only the increase of the total it has seen (see :mod:`teleop.control.energy_channel`).

Flow::

    master --MasterState--> controller --HandCommand--> hand
    master <--ForceCommand-- controller <--HandState--- hand

Encoding and validation live in :mod:`teleop.transport.codec`.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

from teleop.frozen import fast_init

SCHEMA_VERSION = 5  # 2: echo_t_s, echo_held_s in MasterState and HandState; 3: contact models;
#                    4: servo_fault_trips, servo_safe in HandState; 5: hand_echo_t_s in HandCommand
#: a contact model per finger travels as ``(contact_rad, stiffness)`` pairs, fingers 1-3
#: flattened; stiffness 0 = no model for that finger
NO_MODEL = (0.0,) * 6


def scaled_model(model: tuple[float, ...], gain: float) -> tuple[float, ...]:
    """``model`` with every finger's stiffness times ``gain`` (a watchdog's ramp); the
    contact angles stay."""
    return tuple(v * gain if i % 2 else v for i, v in enumerate(model))
N_FINGERS = 3
N_PRESSURE = 9  # per finger: 5 proximal, 4 distal


class HandMode(IntEnum):
    """How the hand interprets finger set-points."""

    POSITION = 0  # finger_setpoint_rad are joint angles
    FORCE = 1     # finger_force_units are tendon force commands (servo units)
    VELOCITY = 2  # position move at a set speed (the stock driver's "velocity mode")
    SAFE = 3      # hold (or open, per config) and ignore set-points


@fast_init
@dataclass(frozen=True, slots=True)
class Header:
    """Fields every message carries."""

    seq: int
    t_s: float
    energy_total_j: float
    version: int = SCHEMA_VERSION


@fast_init
@dataclass(frozen=True, slots=True)
class MasterState:
    """Master -> controller: the grasp trigger's opening and its rate (0 = open)."""

    header: Header
    grip_position_m: float
    grip_velocity_m_s: float
    #: ``t_s`` of the latest ForceCommand the master had received when it sent this (the
    #: controller's clock; negative = none yet): the controller measures the round trip
    #: ``now - echo_t_s`` on its own clock, no clock synchronisation needed.
    echo_t_s: float = -1.0
    #: how long the master had held that ForceCommand when it sent this (s, its own clock)
    echo_held_s: float = 0.0


@fast_init
@dataclass(frozen=True, slots=True)
class ForceCommand:
    """Controller -> master: the force the trigger should display (positive resists closing)."""

    header: Header
    force_n: float
    #: the contact model the master renders locally (model-mediated two-layer): per finger
    #: ``(contact_rad, stiffness_n_per_rad)``, the force on the trigger per rad of that
    #: finger's set-point beyond its contact angle; stiffness 0 = no model
    model: tuple[float, ...] = NO_MODEL


@fast_init
@dataclass(frozen=True, slots=True)
class HandCommand:
    """Controller -> hand: finger set-points, preshape and mode."""

    header: Header
    finger_setpoint_rad: tuple[float, float, float]
    preshape_rad: float
    mode: HandMode = HandMode.POSITION
    finger_force_units: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: ``t_s`` of the latest HandState the controller had when it computed this command (the
    #: hand's clock; negative = none): the hand knows which of its touches the command saw
    hand_echo_t_s: float = -1.0


@fast_init
@dataclass(frozen=True, slots=True)
class FingerState:
    """One finger's measured state."""

    proximal_rad: float
    distal_rad: float  # estimate: max(0, joint angle - proximal)
    motor_angle_rad: float  # joint-side motor angle (raw * scale / ratio - zero)
    load_units: float  # Dynamixel present load, signed (positive pulls the tendon)
    pressure: tuple[float, ...]  # N_PRESSURE values, raw sensor units (0 at rest)
    contact: tuple[bool, ...]  # N_PRESSURE flags: pressure above the contact threshold


@fast_init
@dataclass(frozen=True, slots=True)
class HandState:
    """Hand -> controller: the state of every finger and the preshape joint."""

    header: Header
    fingers: tuple[FingerState, FingerState, FingerState]
    preshape_rad: float
    #: ``t_s`` of the latest HandCommand the hand had received (controller's clock;
    #: negative = none yet), echoed for the controller's round-trip measurement.
    echo_t_s: float = -1.0
    #: how long the hand had held that HandCommand when it sent this (s, its own clock)
    echo_held_s: float = 0.0
    #: the hand's contact estimate per finger ``(contact_rad, stiffness)``: the set-point at
    #: which the finger meets the object and the settled peak pressure per rad beyond it
    #: (raw pressure units / rad); stiffness 0 = no valid estimate
    contact_model: tuple[float, ...] = NO_MODEL
    #: episodes in which servo error bits (overload, overheat, voltage) sent the hand to its
    #: safe state so far, and whether it is held there now
    servo_fault_trips: int = 0
    servo_safe: bool = False


Message = MasterState | ForceCommand | HandCommand | HandState
