"""Test doubles for the service shells: a kinematic hand with one stiff object."""

from __future__ import annotations

from teleop.devices.base import HandReading
from teleop.messages import N_PRESSURE, FingerState, HandCommand


class FakeHand:
    """Three position-servoed fingers (rate-limited) that stop on an object at ``contact_rad``.

    Beyond contact the servo squeezes: pressure rises with how far the set-point lies past the
    object (``pressure_per_rad``), landing on proximal sensors 2 and 3.
    """

    def __init__(self, contact_rad: float = 1.2, speed_rad_s: float = 3.5,
                 pressure_per_rad: float = 200.0) -> None:
        self.contact_rad = contact_rad
        self.speed_rad_s = speed_rad_s
        self.pressure_per_rad = pressure_per_rad
        self.angle = [0.0, 0.0, 0.0]
        self.setpoint = [0.0, 0.0, 0.0]
        self.t_s: float | None = None
        self.applied: list[HandCommand] = []
        self.safe_calls: list[str] = []
        self.started = self.closed = False

    def start(self) -> None:
        self.started = True

    def apply(self, command: HandCommand) -> None:
        self.applied.append(command)
        self.setpoint = list(command.finger_setpoint_rad)

    def read(self, t_s: float) -> HandReading:
        dt = 0.0 if self.t_s is None else t_s - self.t_s
        self.t_s = t_s
        fingers = []
        for i in range(3):
            target = min(self.setpoint[i], self.contact_rad)
            step = max(-self.speed_rad_s * dt, min(self.speed_rad_s * dt, target - self.angle[i]))
            self.angle[i] += step
            squeeze = max(0.0, self.setpoint[i] - self.contact_rad) if \
                self.angle[i] >= self.contact_rad - 1e-9 else 0.0
            p = [0.0] * N_PRESSURE
            p[2] = self.pressure_per_rad * squeeze
            p[3] = 0.5 * p[2]
            fingers.append(FingerState(
                proximal_rad=self.angle[i], distal_rad=0.0, motor_angle_rad=self.angle[i],
                load_units=10.0 * squeeze, pressure=tuple(p),
                contact=tuple(v > 20.0 for v in p)))
        return HandReading(t_s=t_s, fingers=tuple(fingers), preshape_rad=0.0)

    def safe(self, mode: str) -> None:
        self.safe_calls.append(mode)

    def close(self) -> None:
        self.closed = True
