"""The explicit state of one finger (see :mod:`sim.finger` for the model)."""

from __future__ import annotations

from dataclasses import dataclass

from sim.motor import HOLD_ZERO, MotorCommand
from sim.params import FingerParams
from teleop.frozen import fast_init


@fast_init
@dataclass(frozen=True, slots=True)
class FingerState:
    """The explicit state of one finger (true physical values, SI).

    Rarely read values are grouped in tuples (fewer fields make the hot step cheaper); the
    properties below name them.
    """

    t_s: float
    prox_rad: float
    prox_vel_rad_s: float
    flex_rad: tuple[float, ...]
    flex_vel_rad_s: tuple[float, ...]
    motor_rad: float
    motor_vel_rad_s: float
    tendon_force_n: float
    # (backlash gap = shaft - spool angle, servo set-point, effort acting on the motor after
    #  effects and lag, effort the servo asked for before effects)
    drive: tuple[float, float, float, float]
    # (proximal pad contact force N, where along the proximal link m, same for the distal)
    pads: tuple[float, float, float, float]
    # (command in force, last command received, pending delayed commands (due time, command))
    command: tuple[MotorCommand, MotorCommand | None, tuple[tuple[float, MotorCommand], ...]]
    # permanent dent of a yielding object under the (proximal, distal) pad, m (sim.crush):
    # the dent so far, updated from the depth at the start of every step; never shrinks
    crush_m: tuple[float, float] = (0.0, 0.0)

    @property
    def spool_gap_rad(self) -> float:
        """Backlash: motor shaft angle minus spool angle."""
        return self.drive[0]

    @property
    def ref_rad(self) -> float:
        """The servo's internal set-point (shaft rad)."""
        return self.drive[1]

    @property
    def effort_units(self) -> float:
        """Effort acting on the motor (servo units, after effects)."""
        return self.drive[2]

    @property
    def cmd_effort_units(self) -> float:
        """Effort the servo asked for (servo units, before effects)."""
        return self.drive[3]

    @property
    def prox_contact_n(self) -> float:
        """Contact force on the proximal pad."""
        return self.pads[0]

    @property
    def dist_contact_n(self) -> float:
        """Contact force on the distal pad."""
        return self.pads[2]

    @property
    def active_cmd(self) -> MotorCommand:
        """The command the motor is executing (after any delay)."""
        return self.command[0]


def initial_finger_state(params: FingerParams) -> FingerState:
    """The finger open on its stop, motor at its calibrated zero, tendon just slack."""
    zeros = (0.0,) * params.n_flex
    return FingerState(0.0, 0.0, 0.0, zeros, zeros, 0.0, 0.0, 0.0, (0.0, 0.0, 0.0, 0.0),
                       (0.0, 0.0, 0.0, 0.0), (HOLD_ZERO, None, ()))
