"""The seed report's experiments on the simulated finger, each producing a recording.

=================  ==========================================================================
``weight``         a weight (``force_n``) hung on the detached tendon; settles to Table 4.2
``pull-unloaded``  the motor pulls an unloaded string with ``units``; Table 4.1's speed
``force-step``     force mode, 60 units from rest (Fig. 4.15)
``force-blocks``   force mode 30, 60, 90 units for 20 s each, then a position return (Fig. 4.16)
``position``       position mode: a sine, then set-point steps (Fig. 3.3)
``grasp``          position mode closing on a cylinder; pressures (Fig. 3.6)
=================  ==========================================================================

Recording columns (SI units in the names): ``t_s``, ``motor_cmd_units`` (force-mode input, or
the servo's effort command in position mode), ``setpoint_rad`` (joint set-point, position
mode), ``tendon_force_n``, ``motor_angle_rad`` (shaft), ``motor_velocity_rad_s``,
``joint_angle_rad`` (shaft / 1.42), ``proximal_angle_rad``, ``distal_angle_rad``,
``motor_load_units``, ``pressure_0`` .. ``pressure_8``.  Noise (optional, seeded) models the
encoders' quantisation, load noise and pressure noise.
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable
from dataclasses import dataclass, replace

from sim.contact import ContactObject
from sim.engine import DEFAULT_ENGINE, engine
from sim.finger import (
    FingerParams,
    FingerState,
    MotorCommand,
    finger_outputs,
    initial_finger_state,
    weight_equilibrium,
)
from sim.params import JOINT_RATIO
from teleop.effects import EffectSet
from teleop.errors import ExperimentError
from teleop.recording import Recording

EXPERIMENTS: tuple[str, ...] = ("weight", "pull-unloaded", "force-step", "force-blocks",
                                "position", "grasp")
COLUMNS: tuple[str, ...] = (
    "t_s", "motor_cmd_units", "setpoint_rad", "tendon_force_n", "motor_angle_rad",
    "motor_velocity_rad_s", "joint_angle_rad", "proximal_angle_rad", "distal_angle_rad",
    "motor_load_units", *(f"pressure_{i}" for i in range(9)))
DEFAULT_DURATION_S = {"weight": 10.0, "pull-unloaded": 3.0, "force-step": 60.0,
                      "force-blocks": 70.0, "position": 20.0, "grasp": 6.0}
PROXIMAL_COUNT_RAD = 2.0 * math.pi / 16383.0   # AS5048A
MOTOR_COUNT_RAD = 8.0 * math.pi / 4095.0       # MX-28 multi-turn, resolution divider 4

Schedule = Callable[[float], tuple[MotorCommand, float]]  # t -> (command, joint set-point)


@dataclass(frozen=True, slots=True)
class ExperimentSpec:
    """What to run: the experiment, its argument and the simulation options."""

    name: str
    duration_s: float | None = None
    force_n: float = 9.8
    units: float = 100.0
    rate_hz: float = 100.0
    dt_s: float = 1e-3
    noise: bool = False
    seed: int = 0


@dataclass(frozen=True, slots=True)
class ExperimentResult:
    """A recording plus the experiment's headline figures (flat, units in keys)."""

    recording: Recording
    summary: dict[str, float | str]


def check_spec(spec: ExperimentSpec) -> None:
    """One-line ExperimentError for an unknown experiment or a bad argument."""
    if spec.name not in EXPERIMENTS:
        raise ExperimentError(f"unknown experiment {spec.name!r} (known: "
                              f"{', '.join(EXPERIMENTS)})")
    for label, value in (("--force-n", spec.force_n), ("--units", spec.units)):
        if not math.isfinite(value) or value < 0.0:
            raise ExperimentError(f"{label} {value}: must be a finite number >= 0")
    if spec.units > 1023.0:
        raise ExperimentError(f"--units {spec.units}: the MX-28 accepts at most 1023")
    if spec.duration_s is not None and (not math.isfinite(spec.duration_s)
                                        or spec.duration_s <= 0.0):
        raise ExperimentError(f"--duration {spec.duration_s}: must be a finite number > 0")
    if not math.isfinite(spec.rate_hz) or spec.rate_hz <= 0.0:
        raise ExperimentError(f"--rate-hz {spec.rate_hz}: must be a finite number > 0")


def _force(units: float) -> MotorCommand:
    return MotorCommand("force", force_units=units)


def _position(joint_rad: float) -> MotorCommand:
    return MotorCommand("position", goal_rad=JOINT_RATIO * joint_rad)


def _schedule(spec: ExperimentSpec) -> Schedule:
    """The command as a function of time for the dynamic experiments."""
    if spec.name == "pull-unloaded":
        cmd = _force(spec.units)
        return lambda t: (cmd, 0.0)
    if spec.name == "force-step":
        c0, c60 = _force(0.0), _force(60.0)
        return lambda t: (c60 if t >= 1.0 else c0, 0.0)
    if spec.name == "force-blocks":
        blocks = (_force(0.0), _force(30.0), _force(60.0), _force(90.0))
        back = _position(0.0)

        def blocks_at(t: float) -> tuple[MotorCommand, float]:
            if t < 1.0:
                return blocks[0], 0.0
            k = int((t - 1.0) // 20.0) + 1
            return (blocks[k], 0.0) if k <= 3 else (back, 0.0)
        return blocks_at
    if spec.name == "position":
        steps = (0.3, 1.0, 0.5, 1.2, 0.2, 0.8)

        def position_at(t: float) -> tuple[MotorCommand, float]:
            if t < 10.0:  # sine 0.5 Hz, 0.2 .. 1.0 rad
                sp = 0.6 - 0.4 * math.cos(2.0 * math.pi * 0.5 * t)
            else:
                sp = steps[min(int((t - 10.0) // 2.0), len(steps) - 1)]
            sp = round(sp, 4)  # set-points as the driver sends them (fewer new commands)
            return _position(sp), sp
        return position_at
    if spec.name == "grasp":
        def grasp_at(t: float) -> tuple[MotorCommand, float]:
            sp = 0.0 if t < 0.5 else min(1.6, 0.8 * (t - 0.5))
            sp = round(sp, 3)
            return _position(sp), sp
        return grasp_at
    raise ExperimentError(f"unknown experiment {spec.name!r}")  # pragma: no cover


def _row(t: float, state: FingerState, params: FingerParams, obj: ContactObject,
         effects: EffectSet, setpoint: float, mode: str, cmd_units: float,
         rng: random.Random | None) -> list[float]:
    out = finger_outputs(state, params, obj, effects)
    motor = out.motor_angle_rad
    prox = out.proximal_rad
    load = out.motor_load_units
    pressure = list(out.pressure)
    if rng is not None:
        motor = round((motor + rng.gauss(0.0, 0.002)) / MOTOR_COUNT_RAD) * MOTOR_COUNT_RAD
        prox = round((prox + rng.gauss(0.0, 0.002)) / PROXIMAL_COUNT_RAD) * PROXIMAL_COUNT_RAD
        load = float(round(load + rng.gauss(0.0, 3.0)))
        pressure = [float(round(v + rng.gauss(0.0, 1.5))) for v in pressure]
    return [t, cmd_units if mode == "force" else state.cmd_effort_units, setpoint,
            out.tendon_force_n, motor, out.motor_velocity_rad_s, motor / JOINT_RATIO, prox,
            out.distal_rad, load, *pressure]


def run_experiment(spec: ExperimentSpec, params: FingerParams, obj: ContactObject,
                   effects: EffectSet,
                   progress: Callable[[float], None] | None = None,
                   engine_name: str = DEFAULT_ENGINE) -> ExperimentResult:
    """Run ``spec`` on the finger with the physics engine ``engine_name`` (``sim.engine``);
    ``progress(fraction)`` is called about every 10 %."""
    check_spec(spec)
    duration = spec.duration_s or DEFAULT_DURATION_S[spec.name]
    dt = spec.dt_s
    steps = int(round(duration / dt))
    every = max(1, int(round(1.0 / (spec.rate_hz * dt))))
    rng = random.Random(spec.seed) if spec.noise else None
    if spec.name == "pull-unloaded":
        params = replace(params, tendon_slack_m=10.0)  # the string is not tied to the finger
    if spec.name in ("weight", "pull-unloaded"):
        obj = ContactObject(kind="none")
    elif spec.name != "grasp" and obj.kind != "none":
        obj = ContactObject(kind="none")  # free-motion experiments: nothing in the way
    state = initial_finger_state(params)
    schedule = None if spec.name == "weight" else _schedule(spec)
    hold = (MotorCommand("force"), 0.0)
    plan = [hold] * (steps + 1) if schedule is None else [schedule(k * dt)
                                                          for k in range(steps + 1)]
    record = [k % every == 0 for k in range(steps + 1)]
    eng = engine(engine_name)
    hung = spec.force_n if schedule is None else -1.0
    report_every = max(1, steps // 10)
    states: list[FingerState] = []
    start = 0
    while start < steps:  # chunks end after the steps at which progress is reported
        end = min(steps, -(-max(start, 1) // report_every) * report_every + 1)
        last = end == steps
        state, got = eng.run_finger(state, [c for c, _ in plan[start:end]], [dt] * (end - start),
                                    params, obj, effects, [*record[start:end], last and
                                                           record[steps]], hung)
        states.extend(got)
        if progress is not None and (end - 1) % report_every == 0 and end > 1:
            progress((end - 1) / steps)
        start = end
    if steps == 0:
        states.append(state)
    ks = [k for k in range(steps + 1) if record[k]]
    rows = [_row(k * dt, st, params, obj, effects, plan[k][1], plan[k][0].mode,
                 plan[k][0].force_units, rng) for k, st in zip(ks, states, strict=True)]
    rec = Recording.from_columns({c: [r[i] for r in rows] for i, c in enumerate(COLUMNS)},
                                 meta=(("experiment", spec.name),
                                       ("effects", ",".join(f"{n}={getattr(effects, n)}"
                                                            for n in effects.active()) or "none"),
                                       ("seed", str(spec.seed)), ("noise", str(spec.noise)),
                                       ("physics_dt_s", str(dt)), ("object", obj.kind)))
    return ExperimentResult(rec, _summary(spec, rec, params, effects, engine_name))


def _summary(spec: ExperimentSpec, rec: Recording, params: FingerParams,
             effects: EffectSet, engine_name: str) -> dict[str, float | str]:
    last = rec.data[-1]
    col = {c: i for i, c in enumerate(rec.columns)}
    out: dict[str, float | str] = {"experiment": spec.name, "duration_s": float(last[0])}
    if spec.name == "weight":
        prox, dist = weight_equilibrium(params, spec.force_n, effects=effects,
                                        engine_name=engine_name)
        out.update({"force_n": spec.force_n, "proximal_angle_rad": prox,
                    "distal_angle_rad": dist})
    elif spec.name == "pull-unloaded":
        t = rec.t_s
        sel = t >= t[-1] - 0.5 * (t[-1] - t[0])
        ang = rec.column("motor_angle_rad")[sel]
        tt = t[sel]
        slope = float(((tt - tt.mean()) * (ang - ang.mean())).sum()
                      / ((tt - tt.mean()) ** 2).sum())
        out.update({"motor_input_units": spec.units, "motor_velocity_rad_s": slope,
                    "terminal_velocity_rad_s": slope,
                    "joint_velocity_rad_s": slope / JOINT_RATIO,
                    "damping_units_s_per_rad": spec.units / slope if slope > 0 else math.inf})
    else:
        out.update({"final_motor_angle_rad": float(last[col["motor_angle_rad"]]),
                    "final_proximal_angle_rad": float(last[col["proximal_angle_rad"]]),
                    "final_distal_angle_rad": float(last[col["distal_angle_rad"]]),
                    "final_tendon_force_n": float(last[col["tendon_force_n"]]),
                    "peak_motor_load_units": float(abs(rec.column("motor_load_units")).max()),
                    "peak_pressure": float(max(rec.column(f"pressure_{i}").max()
                                               for i in range(9)))})
    return out
