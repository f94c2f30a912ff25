"""The interface every controller implements: parameters, per-role outputs, the suite.

A controller is three pure (init, step) pairs, one per role:

* master side (1 kHz, owns the operator's port)::

      step(state, params, grip_position_m, command: ForceCommand | None, dt_s)
          -> (state, MasterOutput)

* controller (NUC, 1 kHz; transparency layer, energy store/forwarding)::

      step(state, params, master: MasterState | None, hand: HandState | None, t_s, dt_s)
          -> (state, ControllerOutput)

* hand side (hand rate, owns the environment port)::

      step(state, params, fingers: tuple[FingerState, ...], command: HandCommand | None, dt_s)
          -> (state, HandOutput)

``command``/``master``/``hand`` are the latest messages received (None before the first).
Every output carries an :class:`~teleop.control.energy_channel.EnergyLedger` with the side's
cumulative energy accounts, so :func:`~teleop.control.energy_channel.energy_balance` can check
passivity at any sample.  No I/O, no clocks: the services own time and transport.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from teleop.config.control import ContactModelConfig, ControllerConfig
from teleop.control.delay_adapt import DelayAdaptParams, delay_adapt_params
from teleop.control.energy_channel import EnergyLedger
from teleop.control.object_port import TactileModel
from teleop.frozen import fast_init
from teleop.messages import NO_MODEL, ForceCommand, HandCommand, Header, MasterState


@dataclass(frozen=True, slots=True)
class ControlParams:
    """Flat, validated controller parameters (built from ``ControllerConfig``)."""

    kind: str
    # tanks
    initial_j: float
    desired_j: float
    max_j: float
    min_j: float
    reserve_j: float
    transfer_fraction: float
    controller_fraction: float
    tlc_gain: float
    tlc_damping_max: float
    controller_split: float
    # port models
    trigger_max_speed_m_s: float
    trigger_mass_kg: float
    force_max_n: float
    servo_stiffness_nm_per_rad: float
    servo_damping_nm_s_per_rad: float
    servo_torque_max_nm: float
    servo_max_speed_rad_s: float
    energy_scale: float
    # transparency
    finger_enable: tuple[bool, ...]
    trigger_travel_m: float
    open_angle_rad: float
    closed_angle_rad: float
    map_exponent: float
    preshape_rad: float
    force_per_pressure_n: float
    force_combine: str
    force_filter_hz: float
    pressure_deadband: float = 0.0
    # delay-aware force gain (two-layer; None = off)
    delay_adapt: DelayAdaptParams | None = None
    # two-layer hand: servo work on a finger touching nothing goes back to the tank
    free_motion_refund: bool = True
    # two-layer hand: "object" (pay the work on the object) or "servo" (pay the servo spring)
    hand_port: str = "object"
    tendon_stiffness_nm_per_rad: float = 5.0
    finger_kinetic_j: float = 0.015
    tactile: TactileModel = TactileModel()
    # two-layer: model-mediated rendering (None = off; needs the linear trigger map)
    contact_model: ContactModelConfig | None = None


def control_params(cfg: ControllerConfig) -> ControlParams:
    """Flatten the config section into :class:`ControlParams`."""
    t, pm, tr = cfg.tank, cfg.ports, cfg.transparency
    return ControlParams(
        kind=cfg.kind, initial_j=t.initial_j, desired_j=t.desired_j, max_j=t.max_j,
        min_j=t.min_j, reserve_j=t.reserve_j, transfer_fraction=t.transfer_fraction,
        controller_fraction=t.controller_fraction, tlc_gain=t.tlc_gain,
        tlc_damping_max=t.tlc_damping_max, controller_split=t.controller_split,
        trigger_max_speed_m_s=pm.trigger_max_speed_m_s, trigger_mass_kg=pm.trigger_mass_kg,
        force_max_n=pm.force_max_n, servo_stiffness_nm_per_rad=pm.servo_stiffness_nm_per_rad,
        servo_damping_nm_s_per_rad=pm.servo_damping_nm_s_per_rad,
        servo_torque_max_nm=pm.servo_torque_max_nm, energy_scale=t.energy_scale,
        servo_max_speed_rad_s=pm.servo_max_speed_rad_s,
        finger_enable=tuple(tr.finger_enable) + (False,) * (3 - len(tr.finger_enable)),
        trigger_travel_m=tr.trigger_travel_m, open_angle_rad=tr.open_angle_rad,
        closed_angle_rad=tr.closed_angle_rad, map_exponent=tr.map_exponent,
        preshape_rad=tr.preshape_rad, force_per_pressure_n=tr.force_per_pressure_n,
        force_combine=tr.force_combine, force_filter_hz=tr.force_filter_hz,
        pressure_deadband=tr.pressure_deadband,
        delay_adapt=delay_adapt_params(cfg) if cfg.kind == "two-layer" else None,
        free_motion_refund=pm.free_motion_refund, hand_port=pm.hand_port,
        tendon_stiffness_nm_per_rad=pm.tendon_stiffness_nm_per_rad,
        finger_kinetic_j=pm.finger_kinetic_j,
        tactile=TactileModel(**{f: getattr(cfg.tactile, f)
                                for f in TactileModel.__dataclass_fields__}),
        contact_model=(cfg.contact_model if cfg.kind == "two-layer" and cfg.contact_model.enabled
                       and tr.map_exponent == 1.0 else None))


@fast_init
@dataclass(frozen=True, slots=True)
class MasterOutput:
    """What the master side does this sample."""

    force_n: float  # display on the trigger until the next sample (positive resists closing)
    grip_position_m: float  # MasterState fields to send
    grip_velocity_m_s: float
    energy_total_j: float  # cumulative energy sent (MasterState.header.energy_total_j)
    ledger: EnergyLedger
    force_desired_n: float  # what the transparency layer asked for
    limited: bool  # the passivity layer reduced the force
    tlc_damping_n_s_per_m: float  # tank level controller damping in use
    model_force_n: float = 0.0  # the locally rendered contact model's force (two-layer)
    model_phase: float = 0.0  # share of the received contact model rendered (0: none)


def master_message(out: MasterOutput, seq: int, t_s: float, echo_t_s: float = -1.0,
                   echo_held_s: float = 0.0) -> MasterState:
    """The MasterState message for ``out`` (the service owns ``seq`` and ``t_s``);
    ``echo_t_s``: ``t_s`` of the latest ForceCommand received (negative: none yet),
    ``echo_held_s``: how long ago it was received."""
    return MasterState(header=Header(seq=seq, t_s=t_s, energy_total_j=out.energy_total_j),
                       grip_position_m=out.grip_position_m,
                       grip_velocity_m_s=out.grip_velocity_m_s, echo_t_s=echo_t_s,
                       echo_held_s=max(echo_held_s, 0.0))


@fast_init
@dataclass(frozen=True, slots=True)
class ControllerOutput:
    """The two commands the controller sends this cycle, and its accounts."""

    force_command: ForceCommand
    hand_command: HandCommand
    ledger: EnergyLedger  # store_j is ledger.tank_j; port_in/out stay 0 (no physical port)
    max_pressure: tuple[float, float, float]  # per finger (raw units), disabled fingers 0
    force_desired_n: float  # transparency layer's force before the filter
    force_gain: float = 1.0  # delay-aware force-feedback gain in use (two-layer; else 1)
    round_trip_s: float = float("nan")  # round trip that gain is scheduled on (nan: none)


@fast_init
@dataclass(frozen=True, slots=True)
class HandOutput:
    """What the hand side does this sample."""

    setpoint_rad: tuple[float, float, float]  # send these to the position-controlled fingers
    preshape_rad: float
    energy_total_j: float  # cumulative energy sent (HandState.header.energy_total_j)
    ledger: EnergyLedger
    setpoint_desired_rad: tuple[float, float, float]  # what the command asked for
    limited: bool  # set-position modulation moved the set-point
    spring_energy_j: float  # servo layer: modelled servo spring energy; object layer: what the
    # fingers hold back (servo potential + tendon stretch at the set-point, the reservation)
    contact_model: tuple[float, ...] = NO_MODEL  # HandState.contact_model to send
    model_fallbacks: int = 0  # contact estimates dropped as diverged so far (all fingers)
    yielding: int = 0  # fingers whose contact yields (charged at the servo's torque)
    unseen: int = 0  # fingers stalled on a contact the cells do not see (charged the same)
    cells_low: int = 0  # fingers whose cells read lower than the servo's load implies


@dataclass(frozen=True, slots=True)
class ControllerSuite:
    """One controller: an (init_state, step) pair per role, sharing ``ControlParams``."""

    name: str
    init_master: Callable[[ControlParams], Any]
    step_master: Callable[..., tuple[Any, MasterOutput]]
    init_controller: Callable[[ControlParams], Any]
    step_controller: Callable[..., tuple[Any, ControllerOutput]]
    init_hand: Callable[[ControlParams], Any]
    step_hand: Callable[..., tuple[Any, HandOutput]]
    passive: bool  # whether the controller claims passivity for any delay/loss
