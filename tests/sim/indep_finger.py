"""An independent generator of dynamic finger recordings for the ``--model finger`` proof.

Only the recording FORMAT is the project's (what ``teleop sim force-step|position --out R.csv``
writes: the ``# experiment:`` line that tells the diagnosis which protocol mode each row is in,
the columns, 100 Hz); the physics is :mod:`indep_finger_physics` (own lumping, own friction law,
own RK4), and the inputs are this module's own:

* ``force`` (``# experiment: force-step``, force mode throughout): random effort blocks, 45-110
  units up and 0-25 units down (the springs pull the finger back), ramped over 0-60 ms;
* ``position`` (``# experiment: position``, position mode throughout): a 0.4-0.8 Hz sine of
  random amplitude, then random set-point steps 0.1-1.3 rad of joint angle.

The truth is drawn 5-20 % off the nominal finger the diagnosis assumes
(``sim.params.default_finger_params``; the generator's defaults equal it, checked by a test):
motor gain ``units_per_n``, motor Coulomb friction, base spring (the three the diagnosis
refines within +-20 %), and the flexure stiffness and tendon stiffness (which it does not
refine: model error it must cope with).  Gaussian noise 0.5-2 mrad, then the MX-28 encoder's
4096 counts per revolution on the motor angle (the AS5048A's 16384 on the proximal one).
One concealed effect per case; ``cogging`` (a position-periodic torque on the shaft) is outside
the catalog.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from teleop.recording import Recording
from tests.sim.indep_finger_physics import (
    Command,
    Effects,
    FingerTruth,
    Trajectory,
    simulate,
)

RATE_HZ = 100.0
DURATION_S = 6.0
MOTOR_COUNT_RAD = 2 * math.pi / 4096
PROXIMAL_COUNT_RAD = 2 * math.pi / 16384
JOINT_RATIO = 1.42
KINDS = ("force", "position")
EXPERIMENT = {"force": "force-step", "position": "position"}
CATALOG = ("coulomb_friction", "actuator_lag", "dead_time", "sensor_offset", "backlash",
           "actuator_gain")
PERTURBED = ("units_per_n", "motor_coulomb_units", "k_base_nm_per_rad", "k_flex_nm_per_rad",
             "k_tendon_n_per_m")


@dataclass(frozen=True)
class FingerCase:
    """One generated recording, its kind, the concealed effect and the truth."""

    recording: Recording
    kind: str
    concealed: str | None
    value: float
    truth: FingerTruth
    trajectory: Trajectory
    command: Callable[[float], Command] | None = None  # the protocol's command at time t
    noise_rad: float = 0.0                              # the sensors' Gaussian noise, std


def signature(c: FingerCase) -> float:
    """How much the concealed effect itself shows in the motor angle, over the noise: the rms
    difference between the case's true motor angle (plus any sensor offset) and the same truth
    simulated under the same command without the effect, divided by the noise's std (0 for a
    clean case).  The generator's own physics alone: whatever a diagnosis makes of the
    recording, an effect whose signature is under the noise is not in the data to be found."""
    if c.concealed is None or c.command is None or not c.noise_rad > 0.0:
        return 0.0
    twin = simulate(c.command, DURATION_S, RATE_HZ, c.truth, Effects())
    offset = c.value if c.concealed == "sensor_offset" else 0.0
    d = c.trajectory.motor_rad + offset - twin.motor_rad
    return float(np.sqrt(np.mean(d ** 2))) / c.noise_rad


def _blocks(rng: np.random.Generator) -> list[tuple[float, float, float]]:
    """(start s, level units, ramp s) of the force protocol."""
    out, t, up = [], float(rng.uniform(0.3, 0.8)), True
    while t < DURATION_S:
        level = rng.uniform(45.0, 110.0) if up else rng.uniform(0.0, 25.0)
        out.append((t, float(level), float(rng.uniform(0.0, 0.06))))
        t += float(rng.uniform(0.7, 1.5))
        up = not up
    return out


def _force_at(blocks: list[tuple[float, float, float]]) -> Callable[[float], float]:
    def at(t: float) -> float:
        u = 0.0
        for t0, level, ramp in blocks:
            if t < t0:
                break
            frac = 1.0 if ramp <= 0.0 else min(1.0, (t - t0) / ramp)
            u += frac * (level - u)   # ramped from the previous block's level
        return u
    return at


def _setpoints(rng: np.random.Generator) -> Callable[[float], float]:
    """Joint set-point (rad) as a function of time, rounded as the driver sends it."""
    f, lo, hi = rng.uniform(0.4, 0.8), rng.uniform(0.1, 0.3), rng.uniform(0.8, 1.2)
    t_sine = float(rng.uniform(2.0, 3.0))
    steps, t = [], t_sine
    while t < DURATION_S:
        steps.append((t, float(rng.uniform(0.1, 1.3))))
        t += float(rng.uniform(0.8, 1.5))

    def at(t: float) -> float:
        if t < t_sine:
            sp = lo + 0.5 * (hi - lo) * (1 - math.cos(2 * math.pi * f * t))
        else:
            sp = [v for t0, v in steps if t0 <= t][-1]
        return round(sp, 4)
    return at


def _effect(concealed: str | None, rng: np.random.Generator) -> tuple[Effects, float]:
    sgn = 1.0 if rng.random() < 0.5 else -1.0
    if concealed is None:
        return Effects(), 0.0
    if concealed == "coulomb_friction":
        v = float(rng.uniform(0.8, 2.0))
        return Effects(coulomb_friction_n=v), v
    if concealed == "actuator_lag":
        v = float(rng.uniform(0.03, 0.1))
        return Effects(actuator_lag_s=v), v
    if concealed == "dead_time":
        v = float(rng.uniform(0.03, 0.1))
        return Effects(dead_time_s=v), v
    if concealed == "sensor_offset":
        v = sgn * float(rng.uniform(0.03, 0.1))
        return Effects(sensor_offset_rad=v), v
    if concealed == "backlash":
        v = float(rng.uniform(0.02, 0.06))
        return Effects(backlash_rad=v), v
    if concealed == "actuator_gain":
        v = float(rng.uniform(0.4, 0.6) if sgn > 0 else rng.uniform(1.7, 2.2))
        return Effects(actuator_gain=v), v
    if concealed == "cogging":
        v = float(rng.uniform(0.5, 1.5))
        return Effects(cogging_n=v, cogging_period_rad=float(rng.uniform(0.1, 0.3))), v
    raise ValueError(f"unknown concealed effect {concealed!r}")


def draw_truth(rng: np.random.Generator) -> FingerTruth:
    """The nominal finger with each of :data:`PERTURBED` 5-20 % off (random sign)."""
    nom = FingerTruth()
    off = rng.uniform(0.05, 0.2, len(PERTURBED)) * np.where(
        rng.random(len(PERTURBED)) < 0.5, -1.0, 1.0)
    return replace(nom, **{n: getattr(nom, n) * (1.0 + float(o))
                           for n, o in zip(PERTURBED, off, strict=True)})


def make(concealed: str | None, seed: int, kind: str | None = None,
         truth: FingerTruth | None = None, law: str = "speed") -> FingerCase:
    """Generate one recording (``kind`` defaults to alternating with the seed; ``law`` the
    motor friction law, :class:`FingerTruth.friction_law`)."""
    rng = np.random.default_rng(seed)
    kind = kind or KINDS[seed % 2]
    p = replace(draw_truth(rng), friction_law=law) if truth is None else truth
    eff, value = _effect(concealed, rng)
    if kind == "force":
        force = _force_at(_blocks(rng))

        def command(t: float) -> Command:
            return Command("force", units=force(t))
        sp = np.zeros(int(round(DURATION_S * RATE_HZ)))
    else:
        joint = _setpoints(rng)

        def command(t: float) -> Command:
            return Command("position", goal_rad=JOINT_RATIO * joint(t))
    tr = simulate(command, DURATION_S, RATE_HZ, p, eff)
    t = tr.t_s
    if kind == "position":
        sp = np.array([joint(ti) for ti in t])
        u = tr.effort_units        # the servo's effort, as the project's position rows log
    else:
        u = np.array([force(ti) for ti in t])
    sigma = float(rng.uniform(5e-4, 2e-3))
    motor = tr.motor_rad + eff.sensor_offset_rad + sigma * rng.standard_normal(len(t))
    motor = np.round(motor / MOTOR_COUNT_RAD) * MOTOR_COUNT_RAD
    prox = tr.proximal_rad + eff.sensor_offset_rad + sigma * rng.standard_normal(len(t))
    prox = np.round(prox / PROXIMAL_COUNT_RAD) * PROXIMAL_COUNT_RAD
    rec = Recording.from_columns(
        {"t_s": t, "motor_cmd_units": u, "setpoint_rad": sp, "tendon_force_n": tr.tendon_n,
         "motor_angle_rad": motor, "motor_velocity_rad_s": tr.motor_vel_rad_s,
         "joint_angle_rad": motor / JOINT_RATIO, "proximal_angle_rad": prox,
         "distal_angle_rad": tr.distal_rad, "motor_load_units": tr.tendon_n * p.units_per_n},
        (("experiment", EXPERIMENT[kind]), ("generator", "tests/sim/indep_finger.py"),
         ("seed", str(seed)), ("noise", "True")))
    return FingerCase(rec, kind, concealed, value, p, tr, command, sigma)
