"""The ReFlex hand: three tendon fingers (sim.finger) plus the preshape joint.

The preshape MX-28 (motor-to-joint ratio 1.5, travel 1.75 rad) swivels fingers 1 and 2 in
opposite directions about axes along the palm normal (finger 3, the thumb, does not swivel).
It is modelled as one joint driven by the servo's P controller (torque-limited) with viscous
friction, integrated implicitly.  Each finger sees the object in its own plane (the same
``ContactObject`` for all three unless a tuple of three is given); the swivel does not move the
object in the finger's plane (a simplification: objects are placed per finger plane).
"""

from __future__ import annotations

from dataclasses import dataclass

from sim.contact import ContactObject
from sim.finger import (
    FingerOutputs,
    FingerParams,
    FingerState,
    MotorCommand,
    default_finger_params,
    finger_outputs,
    finger_step,
    initial_finger_state,
)
from teleop.effects import EffectSet
from teleop.frozen import fast_init

N_FINGERS = 3
PRESHAPE_RATIO = 1.5


@dataclass(frozen=True, slots=True)
class HandParams:
    """Constants of the hand: the finger model (shared by all three) and the preshape joint."""

    finger: FingerParams
    preshape_inertia_kg_m2: float = 2.0e-3     # swivel gears + two fingers (estimate)
    preshape_kp_nm_per_rad: float = 8.0        # servo P gain referred to the joint
    preshape_damping_nm_s_per_rad: float = 1.2  # gear friction referred to the joint
    preshape_max_torque_nm: float = 2.5 * PRESHAPE_RATIO  # stall torque through the ratio
    preshape_limits_rad: tuple[float, float] = (0.0, 1.75)


def default_hand_params(finger: FingerParams | None = None) -> HandParams:
    """The default hand (calibrated fingers)."""
    return HandParams(finger=finger or default_finger_params())


@fast_init
@dataclass(frozen=True, slots=True)
class HandMotorCommand:
    """Commands for the three finger motors and the preshape joint goal (joint rad)."""

    fingers: tuple[MotorCommand, MotorCommand, MotorCommand]
    preshape_goal_rad: float = 0.0


@fast_init
@dataclass(frozen=True, slots=True)
class HandSimState:
    """The explicit state of the hand."""

    t_s: float
    fingers: tuple[FingerState, FingerState, FingerState]
    preshape_rad: float
    preshape_vel_rad_s: float


@fast_init
@dataclass(frozen=True, slots=True)
class HandOutputs:
    """Measurements of the hand."""

    t_s: float
    fingers: tuple[FingerOutputs, FingerOutputs, FingerOutputs]
    preshape_rad: float
    swivel_rad: tuple[float, float, float]  # each finger plane's swivel: (+pre, -pre, 0)


def initial_hand_state(params: HandParams) -> HandSimState:
    """Fingers open, preshape at 0."""
    f = initial_finger_state(params.finger)
    return HandSimState(0.0, (f, f, f), 0.0, 0.0)


def _objects(obj: ContactObject | tuple[ContactObject, ...]) -> tuple[ContactObject, ...]:
    return obj if isinstance(obj, tuple) else (obj, obj, obj)


def preshape_step(angle: float, vel: float, goal: float, params: HandParams,
                  dt: float) -> tuple[float, float]:
    """One implicit step of the preshape joint under its servo (returns angle, speed)."""
    lo, hi = params.preshape_limits_rad
    goal = min(max(goal, lo), hi)
    kp = params.preshape_kp_nm_per_rad
    tmax = params.preshape_max_torque_nm
    m = params.preshape_inertia_kg_m2
    c = params.preshape_damping_nm_s_per_rad
    torque = kp * (goal - angle)
    if abs(torque) < tmax:  # linear region: implicit in the P term too
        vel = (m * vel + dt * torque) / (m + dt * c + dt * dt * kp)
    else:
        torque = tmax if torque > 0 else -tmax
        vel = (m * vel + dt * torque) / (m + dt * c)
    angle += dt * vel
    if angle < lo:
        angle, vel = lo, max(vel, 0.0)
    elif angle > hi:
        angle, vel = hi, min(vel, 0.0)
    return angle, vel


def hand_step(state: HandSimState, cmd: HandMotorCommand, params: HandParams,
              obj: ContactObject | tuple[ContactObject, ...], effects: EffectSet,
              dt_s: float) -> HandSimState:
    """Advance the whole hand by ``dt_s`` (pure)."""
    objs = _objects(obj)
    fp = params.finger
    fs = state.fingers
    f0 = finger_step(fs[0], cmd.fingers[0], fp, objs[0], effects, dt_s)
    f1 = finger_step(fs[1], cmd.fingers[1], fp, objs[1], effects, dt_s)
    f2 = finger_step(fs[2], cmd.fingers[2], fp, objs[2], effects, dt_s)
    ang, vel = preshape_step(state.preshape_rad, state.preshape_vel_rad_s,
                             cmd.preshape_goal_rad, params, dt_s)
    return HandSimState(state.t_s + dt_s, (f0, f1, f2), ang, vel)


def hand_outputs(state: HandSimState, params: HandParams,
                 obj: ContactObject | tuple[ContactObject, ...],
                 effects: EffectSet) -> HandOutputs:
    """Measurements of every finger and the preshape angle."""
    objs = _objects(obj)
    fo = tuple(finger_outputs(state.fingers[i], params.finger, objs[i], effects)
               for i in range(N_FINGERS))
    pre = state.preshape_rad
    return HandOutputs(state.t_s, (fo[0], fo[1], fo[2]), pre, (pre, -pre, 0.0))
