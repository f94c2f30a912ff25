"""What the emulated servos move: the finger model behind a small interface.

The emulator speaks to physics only through :class:`ServoPhysics`: every physics tick it hands
over one :class:`ServoDrive` per servo (what the control table commands, in the servo's own
CCW-positive shaft frame) and reads back one :class:`ServoSense` per servo.

* :class:`FingerServoPhysics` drives ``sim.finger`` (the tendon finger model): the three finger
  servos each pull a finger's tendon (position mode with moving speed and torque limit), present
  load comes from the tendon force, and the finger touches the configured object.  The preshape
  servo is a plain position servo (:class:`SimpleServo`).
* :class:`SimpleServoPhysics` is a FALLBACK used only when ``sim.finger`` cannot be imported:
  a rate-limited position servo with a linear contact spring at a fixed shaft angle.  It is
  labelled as such wherever it is used (``physics.label``).

Direction convention: a finger servo with inversion ``inv`` closes its finger when its shaft
turns by ``inv`` (CCW for +1); the finger model's motor angle is ``inv * (shaft - home)``.
Present-load sign: ``load_pull_units`` is positive while the motor pulls the tendon.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from teleop.devices.dynamixel_tables import MX28_NO_LOAD_SPEED_RAD_S

UNITS_PER_NEWTON = 5.0  # servo load units per newton of tendon force (fallback model)


@dataclass(frozen=True, slots=True)
class ServoDrive:
    """What one servo is told to do (from its control table)."""

    torque_on: bool
    goal_rad: float  # shaft angle target, CCW positive, absolute
    speed_rad_s: float  # moving speed; 0 = as fast as possible
    torque_limit: float  # fraction of max torque, 0..1


@dataclass(frozen=True, slots=True)
class ServoSense:
    """What one servo measures."""

    angle_rad: float  # shaft angle, CCW positive, absolute
    velocity_rad_s: float  # CCW positive
    load_pull_units: float  # signed load units, positive = pulling the tendon (closing)


class ServoPhysics(Protocol):
    """The world the servos move."""

    label: str

    def step(self, drives: Sequence[ServoDrive], dt_s: float, steps: int = 1) -> None:
        """Advance by ``steps`` steps of ``dt_s`` under ``drives`` (one per servo, in bus
        order)."""

    def sense(self) -> tuple[ServoSense, ...]:
        """Current measurements, one per servo."""


@dataclass(frozen=True, slots=True)
class SimpleServoState:
    """State of the fallback servo model (in the finger's closing frame)."""

    angle_rad: float = 0.0
    velocity_rad_s: float = 0.0
    load_pull_units: float = 0.0


def simple_servo_step(state: SimpleServoState, goal_rad: float, drive: ServoDrive,
                      contact_rad: float, stiffness_units_per_rad: float,
                      dt_s: float) -> SimpleServoState:
    """Rate-limited position servo that stalls against a contact spring (pure).

    ``goal_rad`` and the state are in the closing frame; the spring acts beyond ``contact_rad``
    (``math.inf`` = free motion).  The servo stalls where the spring load reaches the torque
    limit (1023 units = 100 %).
    """
    vmax = drive.speed_rad_s if drive.speed_rad_s > 0 else MX28_NO_LOAD_SPEED_RAD_S
    vmax = min(vmax, MX28_NO_LOAD_SPEED_RAD_S)
    if not drive.torque_on:
        vmax = 0.0
    err = goal_rad - state.angle_rad
    v = max(-vmax, min(vmax, err / max(dt_s, 0.02)))  # ~20 ms time constant near the goal
    angle = state.angle_rad + v * dt_s
    spring = max(0.0, angle - contact_rad) * stiffness_units_per_rad
    limit = 1023.0 * drive.torque_limit if drive.torque_on else 0.0
    if spring > limit:  # stalled (or pushed back) where the spring balances the limit
        angle = min(angle, contact_rad + limit / stiffness_units_per_rad)
        spring = max(0.0, angle - contact_rad) * stiffness_units_per_rad
    v_actual = (angle - state.angle_rad) / dt_s if dt_s > 0 else 0.0
    push = 40.0 * math.tanh(err / 0.05) * (1.0 if drive.torque_on else 0.0)
    load = spring + (push if spring == 0.0 else 0.0)
    return SimpleServoState(angle, v_actual, load)


class SimpleServo:
    """One fallback servo in its own frame (home and inversion applied)."""

    def __init__(self, home_rad: float, inversion: int, contact_rad: float = math.inf,
                 stiffness_units_per_rad: float = 800.0) -> None:
        self.home_rad = home_rad
        self.inversion = inversion
        self.contact_rad = contact_rad
        self.stiffness = stiffness_units_per_rad
        self.state = SimpleServoState()

    def step(self, drive: ServoDrive, dt_s: float) -> None:
        goal = self.inversion * (drive.goal_rad - self.home_rad)
        self.state = simple_servo_step(self.state, goal, drive, self.contact_rad, self.stiffness,
                                       dt_s)

    def sense(self) -> ServoSense:
        s = self.state
        return ServoSense(self.home_rad + self.inversion * s.angle_rad,
                          self.inversion * s.velocity_rad_s, s.load_pull_units)


class SimpleServoPhysics:
    """FALLBACK physics: every servo a :class:`SimpleServo`; fingers meet a spring."""

    label = "simple servo model (fallback: sim.finger not available)"

    def __init__(self, homes_rad: Sequence[float], inversions: Sequence[int],
                 contact_rad: float = 1.5) -> None:
        self.servos = [SimpleServo(h, inv, contact_rad if i < 3 else math.inf)
                       for i, (h, inv) in enumerate(zip(homes_rad, inversions, strict=True))]

    def step(self, drives: Sequence[ServoDrive], dt_s: float, steps: int = 1) -> None:
        for _ in range(steps):
            for servo, drive in zip(self.servos, drives, strict=True):
                servo.step(drive, dt_s)

    def sense(self) -> tuple[ServoSense, ...]:
        return tuple(s.sense() for s in self.servos)


class FingerServoPhysics:
    """Finger servos pull ``sim.finger`` tendons; a 4th servo is a plain preshape servo."""

    label = "finger model (sim.finger)"

    def __init__(self, homes_rad: Sequence[float], inversions: Sequence[int],
                 object_cfg: Any = None, effects: Any = None,
                 engine_name: str = "compiled") -> None:
        from sim import audit
        from sim import finger as fm  # the physics helper's module
        from sim.engine import engine
        from teleop.effects import EffectSet

        self._fm = fm
        self._audit = audit
        self._engine = engine(engine_name)
        self.params = fm.default_finger_params()
        self.obj = (fm.contact_object_from_config(object_cfg) if object_cfg is not None
                    else fm.ContactObject(kind="none"))
        self.effects = effects if effects is not None else EffectSet()
        if self.effects.active():
            self.label += " with " + ", ".join(f"{n}={getattr(self.effects, n):g}"
                                               for n in self.effects.active())
        n = len(homes_rad)
        self.n_fingers = min(3, n)
        self.homes = list(homes_rad)
        self.inv = list(inversions)
        self.states = [fm.initial_finger_state(self.params) for _ in range(self.n_fingers)]
        self.extra = [SimpleServo(homes_rad[i], inversions[i]) for i in range(self.n_fingers, n)]
        self._outs = [fm.finger_outputs(s, self.params, self.obj, self.effects)
                      for s in self.states]
        #: per finger: work its pads did on the object so far (J; :mod:`sim.audit`), counted
        #: while ``audit_on`` (tests set it; it costs two pad readouts per finger per batch)
        self.audit_on = False
        self.object_work_j = [0.0] * self.n_fingers
        # compile (or load from numba's cache) now, not on the first step while serving
        self._engine.run_finger(self.states[0], [fm.MotorCommand()], [1e-3], self.params,
                                self.obj, self.effects, [False, False])

    def step(self, drives: Sequence[ServoDrive], dt_s: float, steps: int = 1) -> None:
        fm = self._fm
        for i in range(self.n_fingers):
            d = drives[i]
            cmd = fm.MotorCommand(mode="position",
                                  goal_rad=self.inv[i] * (d.goal_rad - self.homes[i]),
                                  speed_rad_s=d.speed_rad_s, force_units=0.0,
                                  torque_limit=d.torque_limit if d.torque_on else 0.0)
            # one engine call for the batch (the compiled engine: ~8x less CPU than stepping
            # in Python, which a loaded machine could not keep up with in real time)
            before = (self._audit.pad_depths(self.states[i], self.params, self.obj)
                      if self.audit_on else None)
            self.states[i], _ = self._engine.run_finger(
                self.states[i], [cmd] * steps, [dt_s] * steps, self.params, self.obj,
                self.effects, [False] * (steps + 1))
            if before is not None:  # the batch (at most a few ms) as one audit step: the
                # elastic part from its end depths (exact at a constant engaged fraction), the
                # damper's at the batch's mean rate; a touch made and lost inside it is missed
                self.object_work_j[i] += self._audit.object_work_j(
                    before, self._audit.pad_depths(self.states[i], self.params, self.obj),
                    self.obj, dt_s * steps)
        self._outs = []  # computed when next sensed (finger_outputs is as costly as a step)
        for _ in range(steps):
            for servo, d in zip(self.extra, drives[self.n_fingers:], strict=True):
                servo.step(d, dt_s)

    def _outputs(self) -> list[Any]:
        if not self._outs:
            self._outs = [self._fm.finger_outputs(s, self.params, self.obj, self.effects)
                          for s in self.states]
        return self._outs

    def sense(self) -> tuple[ServoSense, ...]:
        outs = self._outputs()
        out = [ServoSense(self.homes[i] + self.inv[i] * o.motor_angle_rad,
                          self.inv[i] * o.motor_velocity_rad_s, o.motor_load_units)
               for i, o in enumerate(outs)]
        return tuple(out) + tuple(s.sense() for s in self.extra)

    def proximal_rad(self) -> tuple[float, ...]:
        """The fingers' true proximal angles (for tests; not on the servo bus)."""
        return tuple(o.proximal_rad for o in self._outputs())

    def touching(self) -> tuple[bool, ...]:
        """Per finger: does the model's finger touch the object now (for tests; the direct-USB
        layout has no tactile cells)."""
        return tuple(any(o.contact) for o in self._outputs())


def build_physics(homes_rad: Sequence[float], inversions: Sequence[int], object_cfg: Any = None,
                  *, prefer_finger: bool = True, effects: Any = None,
                  engine_name: str = "compiled") -> ServoPhysics:
    """The finger model when ``sim.finger`` is importable, else the labelled fallback.

    ``effects`` (a :class:`teleop.effects.EffectSet`) are physical effects of the emulated
    fingers (e.g. extra Coulomb friction, a dead time); the fallback has none.
    """
    reason = ""
    if prefer_finger:
        try:
            return FingerServoPhysics(homes_rad, inversions, object_cfg, effects, engine_name)
        except (ImportError, AttributeError, TypeError) as exc:  # model absent or API mismatch
            reason = f"{type(exc).__name__}: {exc}"
    fallback = SimpleServoPhysics(homes_rad, inversions)
    fallback.label = ("simple servo model (requested)" if not prefer_finger else
                      f"simple servo model (FALLBACK; sim.finger unusable: {reason})")
    return fallback


__all__ = ["ServoDrive", "ServoSense", "ServoPhysics", "SimpleServoPhysics",
           "FingerServoPhysics", "build_physics", "simple_servo_step"]
