"""``SimHand``: the simulated ReFlex hand behind the ``teleop.devices.base.HandBackend`` interface.

Usage::

    hand = SimHand(cfg.hand, seed=1)
    hand.start()
    hand.apply(HandCommand(header, finger_setpoint_rad=(1.0, 1.0, 0.5), preshape_rad=0.2))
    reading = hand.read(t_s=0.025)      # advances the physics to t_s (1 kHz steps by default)
    hand.safe("hold")                   # or "open"

Position mode maps the joint set-points (the driver's joint angle = shaft / 1.42) to motor
shaft goals; force mode sends ``finger_force_units`` to the motors; velocity mode is a position
move at the driver's maximum speed (3.5 rad/s joint).  Readings follow the stock driver:
``motor_angle_rad`` is the joint-side motor angle (shaft / 1.42), ``distal_rad`` the driver's
estimate ``max(0, joint angle - proximal)``, ``load_units`` the signed present load,
``pressure``/``contact`` the 9 tactile sensors (contact above 20 raw; ``hand.sim.tactile_gain``
scales the cells' true gain, a mis-calibrated sensor; ``hand.sim.distal_tactile_gain`` the
distal pad's four alone on top of it).  With
``hand.sim.noise`` the encoders are quantised and loads and pressures noisy (seeded).
"""

from __future__ import annotations

import random
from dataclasses import replace

from sim.contact import contact_object_from_config
from sim.engine import engine
from sim.experiments import MOTOR_COUNT_RAD, PROXIMAL_COUNT_RAD
from sim.finger import MotorCommand, default_finger_params, finger_outputs
from sim.hand import (
    HandMotorCommand,
    HandOutputs,
    HandSimState,
    default_hand_params,
    hand_outputs,
    initial_hand_state,
)
from sim.params import JOINT_RATIO, with_tactile_gain
from teleop.config.hand import HandConfig
from teleop.devices.base import HandReading
from teleop.effects import EffectSet
from teleop.errors import UserInputError
from teleop.messages import FingerState, HandCommand, HandMode

DRIVER_MAX_SPEED_RAD_S = 3.5  # joint rad/s (stock driver)


class SimHand:
    """A simulated hand implementing ``HandBackend`` (start/apply/read/safe/close)."""

    def __init__(self, cfg: HandConfig, seed: int = 0, effects: EffectSet | None = None) -> None:
        fp = default_finger_params(cfg.sim.calibration)
        if cfg.sim.model:  # refined by teleop diagnose --write-params
            from sim.finger_model_file import load_model

            fp, found = load_model(cfg.sim.model, fp)
            effects = effects or found
        if cfg.sim.command_delay:
            fp = replace(fp, command_delay_s=0.09)
        fp = with_tactile_gain(fp, cfg.sim.tactile_gain)
        self.cfg = cfg
        self.params = default_hand_params(fp)
        self.obj = contact_object_from_config(cfg.sim.object)
        self.effects = effects or EffectSet()
        self.dt_s = 1.0 / cfg.sim.physics_rate_hz
        self.state_period_s = 1.0 / cfg.state_rate_hz  # 40 Hz by default, as the driver
        self.state: HandSimState = initial_hand_state(self.params)
        self._rng = random.Random(seed) if cfg.sim.noise else None
        self._engine = engine(cfg.sim.engine)
        self._travel = cfg.dynamixel.finger_travel_rad
        self._distal_gain = cfg.sim.distal_tactile_gain
        hold = MotorCommand("position", 0.0)
        self._cmd = HandMotorCommand((hold, hold, hold), 0.0)
        self.started = False
        # physical energy audit of the environment port (sim.audit), per finger
        self.env_delivered_j = [0.0, 0.0, 0.0]
        self.env_taken_j = [0.0, 0.0, 0.0]

    # --- HandBackend ---------------------------------------------------------------------
    def start(self) -> None:
        """Ready once the physics is (the simulated hand is calibrated at its rest pose): the
        compiled engine is compiled or loaded from its disk cache here, before any loop."""
        if self._engine.name == "compiled":
            from sim.compiled import warm_up

            warm_up(finger=False)
        self.started = True

    def apply(self, command: HandCommand) -> None:
        """Set new motor targets from a validated ``HandCommand``."""
        if command.mode == HandMode.SAFE:
            self.safe("hold")
            return
        cmds = []
        for i in range(3):
            if command.mode == HandMode.FORCE:
                cmds.append(MotorCommand("force", force_units=command.finger_force_units[i]))
                continue
            joint = min(max(command.finger_setpoint_rad[i], 0.0), self._travel)
            if command.mode == HandMode.VELOCITY:
                cmds.append(MotorCommand("velocity", JOINT_RATIO * joint,
                                         speed_rad_s=JOINT_RATIO * DRIVER_MAX_SPEED_RAD_S))
            else:
                cmds.append(MotorCommand("position", JOINT_RATIO * joint))
        self._cmd = HandMotorCommand((cmds[0], cmds[1], cmds[2]), command.preshape_rad)

    def read(self, t_s: float) -> HandReading:
        """Advance the physics to ``t_s`` and read the hand like the stock driver does."""
        audit = (self.env_delivered_j, self.env_taken_j) if self.obj.kind != "none" else None
        steps = max(0, int((t_s - self.state.t_s) / self.dt_s) + 2)  # t_s stops it first
        self.state = self._engine.run_hand(self.state, self._cmd, self.params, self.obj,
                                           self.effects, self.dt_s, steps, t_s, audit)
        out = self.truth()
        fingers = tuple(self._finger_message(out, i) for i in range(3))
        return HandReading(t_s=t_s, fingers=(fingers[0], fingers[1], fingers[2]),
                           preshape_rad=out.preshape_rad)

    def safe(self, mode: str) -> None:
        """``"hold"`` the present motor angles, or ``"open"`` the fingers (position 0)."""
        if mode == "hold":
            goals = tuple(f.motor_rad for f in self.state.fingers)
            pre = self.state.preshape_rad
        elif mode == "open":
            goals = (0.0, 0.0, 0.0)
            pre = self.state.preshape_rad
        else:
            raise UserInputError(f"safe mode {mode!r}: expected 'hold' or 'open'")
        c = tuple(MotorCommand("position", g) for g in goals)
        self._cmd = HandMotorCommand((c[0], c[1], c[2]), pre)

    def close(self) -> None:
        """Nothing to release."""
        self.started = False

    # --- extras for the servo emulator, diagnose and tests ------------------------------
    def port_audit_j(self) -> tuple[float, float]:
        """(delivered, taken): physical work on the object so far, all fingers (sim.audit)."""
        return sum(self.env_delivered_j), sum(self.env_taken_j)

    def truth(self) -> HandOutputs:
        """The noiseless measurements (true physics) of the present state."""
        return hand_outputs(self.state, self.params, self.obj, self.effects)

    def set_motor_commands(self, cmd: HandMotorCommand) -> None:
        """Command the motors directly (shaft goals), bypassing the HandCommand mapping."""
        self._cmd = cmd

    def _finger_message(self, out: HandOutputs, i: int) -> FingerState:
        fo = out.fingers[i]
        prox = fo.proximal_rad
        motor = fo.motor_angle_rad
        load = fo.motor_load_units
        pressure = fo.pressure
        if self._distal_gain != 1.0:  # hand.sim.distal_tactile_gain: readings only
            n = len(self.params.finger.proximal_sensor_x_m)
            pressure = (*pressure[:n], *(v * self._distal_gain for v in pressure[n:]))
        rng = self._rng
        if rng is not None:
            prox = round((prox + rng.gauss(0.0, 0.002)) / PROXIMAL_COUNT_RAD) * PROXIMAL_COUNT_RAD
            motor = round(motor / MOTOR_COUNT_RAD) * MOTOR_COUNT_RAD
            load = float(round(load + rng.gauss(0.0, 3.0)))
            pressure = tuple(float(round(v + rng.gauss(0.0, 1.5))) for v in pressure)
        joint = motor / JOINT_RATIO
        thr = self.params.finger.contact_threshold
        return FingerState(proximal_rad=prox, distal_rad=max(0.0, joint - prox),
                           motor_angle_rad=joint, load_units=load, pressure=pressure,
                           contact=tuple(v > thr for v in pressure))


__all__ = ["SimHand", "finger_outputs"]
