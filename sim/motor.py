"""The MX-28 servo as the finger sees it: commands, the servo's own controller, effort effects.

The MX-28 has no torque register; the report (and the 20-sim model) treats "force mode" as the
motor acting as an effort source of ``units / 5`` N of tendon force.  Position and velocity modes
are the servo's P controller on the (measured) shaft angle, clamped by the torque limit; a new
set-point makes a large error and so a load spike (report Fig. 3.3).  Velocity mode is, as in the
stock driver, a position move at a set speed.

The servo's set-point ramp and P controller are inlined in the hot step
(``sim.finger._step``); the effects on the effort and the friction law are here.  Pure functions
over floats; the delay line and lag state live in :class:`sim.finger.FingerState`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sim.params import FingerParams
from teleop.effects import EffectSet
from teleop.frozen import fast_init

MODES = ("position", "force", "velocity")


@fast_init
@dataclass(frozen=True, slots=True)
class MotorCommand:
    """A command to one finger motor.

    ``goal_rad`` is the motor SHAFT angle target (position/velocity modes; the driver's joint
    angle is shaft / 1.42); ``speed_rad_s`` the moving speed (0 = as fast as it can);
    ``force_units`` the force-mode input in servo units (~5 per newton of tendon force);
    ``torque_limit`` a fraction of the maximum torque.
    """

    mode: str = "position"
    goal_rad: float = 0.0
    speed_rad_s: float = 0.0
    force_units: float = 0.0
    torque_limit: float = 1.0


HOLD_ZERO = MotorCommand()


def apply_effort_effects(u: float, lagged: float, effects: EffectSet, params: FingerParams,
                         dt_s: float) -> float:
    """Gain, saturation (N of tendon force) and first-order lag on the motor effort (units)."""
    if effects.actuator_gain != 1.0:
        u *= effects.actuator_gain
    sat = effects.actuator_saturation
    if sat != math.inf:
        cap = sat * params.units_per_n
        u = min(max(u, -cap), cap)
    tau = effects.actuator_lag
    if tau > 0.0:
        u = lagged + dt_s / (tau + dt_s) * (u - lagged)
    return u


def friction_force_n(v: float, params: FingerParams, effects: EffectSet) -> tuple[float, float]:
    """Regularised Coulomb (+ asymmetric, + Stribeck stiction) friction at shaft speed ``v``.

    Returns (force opposing motion in N of tendon-force equivalent, its non-negative slope
    dF/dv used for the linearly implicit step).
    """
    vs = params.coulomb_velocity_rad_s
    level = params.motor_coulomb_units / params.units_per_n + effects.coulomb_friction
    if effects.stiction > 0.0:
        level += effects.stiction * math.exp(-(v / (20.0 * vs)) ** 2)
    if effects.asymmetric_friction > 0.0 and v > 0.0:
        level += effects.asymmetric_friction
    x = v / vs
    if x > 20.0:
        return level, 0.0
    if x < -20.0:
        return -level, 0.0
    th = math.tanh(x)
    return level * th, level * (1.0 - th * th) / vs
