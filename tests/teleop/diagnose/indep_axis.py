"""An independent generator of driven-axis recordings for the diagnose proof (not the
project's own :mod:`teleop.diagnose.synth` / :mod:`teleop.diagnose.axis_model`).

Own code path throughout: an adaptive Runge-Kutta integrator (``scipy.integrate.solve_ivp``,
RK45) on a smooth (tanh) Coulomb law, the input delayed by interpolation, own input kinds
(multisine, ramped steps), a 12-bit-per-radian encoder quantisation on top of Gaussian noise,
1 kHz sampling.  The nominal model handed to the diagnosis states inertia and stiffness 5-20 %
off the truth (refined within +-30 %, so the truth is inside the bounds).  ``cogging`` is physics outside the catalog (a
position-periodic torque).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from teleop.diagnose.model import AxisNominal
from teleop.recording import Recording

RATE_HZ = 1000.0
COUNT_RAD = 1.0 / 4096
KINDS = ("multisine", "ramped-steps")


@dataclass(frozen=True)
class IndepCase:
    """One generated recording, what is concealed in it, and the stated nominal model."""

    recording: Recording
    concealed: str | None
    value: float
    nominal: AxisNominal
    wavenumber: float = 0.0   # cogging: 2 pi / period (1/rad)


def _input(kind: str, t: np.ndarray, k: float, rng: np.random.Generator) -> np.ndarray:
    if kind == "multisine":
        f = rng.uniform(0.2, 3.0, 6)
        ph = rng.uniform(0, 2 * math.pi, 6)
        u = sum(np.sin(2 * math.pi * fi * t + p) for fi, p in zip(f, ph, strict=True))
        return 0.5 * k * u / np.max(np.abs(u))
    u = np.zeros_like(t)
    level, tt = 0.0, 0.2
    while tt < t[-1]:
        new = rng.uniform(0.3, 0.9) * k * (-1 if level > 0 else 1)
        ramp = rng.uniform(0.02, 0.1)
        u += np.clip((t - tt) / ramp, 0, 1) * (new - level)
        level, tt = new, tt + rng.uniform(0.5, 1.1)
    return u


def make(concealed: str | None, seed: int, duration_s: float = 4.0) -> IndepCase:
    """Generate one recording with ``concealed`` (or nothing) at a random magnitude."""
    rng = np.random.default_rng(seed)
    m = rng.uniform(0.4, 2.5)
    k = m * (2 * math.pi * rng.uniform(0.8, 2.2)) ** 2
    c = 2 * rng.uniform(0.04, 0.2) * math.sqrt(k * m)
    t = np.arange(int(duration_s * RATE_HZ)) / RATE_HZ
    u = _input(KINDS[seed % 2], t, k, rng)
    sgn = 1 if rng.random() < 0.5 else -1
    value = {None: 0.0, "coulomb_friction": rng.uniform(0.06, 0.15) * k,
             "dead_time": rng.uniform(0.03, 0.1), "sensor_offset": sgn * rng.uniform(0.05, 0.2),
             "actuator_gain": rng.choice([rng.uniform(0.5, 0.7), rng.uniform(1.4, 1.8)]),
             "actuator_saturation": rng.uniform(0.45, 0.7) * float(np.max(np.abs(u))),
             "cogging": rng.uniform(0.1, 0.2) * k}[concealed]
    period = rng.uniform(0.15, 0.3)
    delay = value if concealed == "dead_time" else 0.0

    def effort(ti: float) -> float:
        f = float(np.interp(ti - delay, t, u, left=0.0))
        if concealed == "actuator_saturation":
            f = min(max(f, -value), value)
        return f * (value if concealed == "actuator_gain" else 1.0)

    def rhs(ti: float, s: np.ndarray) -> list[float]:
        x, v = s
        a = effort(ti) - c * v - k * x
        if concealed == "coulomb_friction":
            a -= value * math.tanh(v / 1e-3)
        if concealed == "cogging":
            a -= value * math.sin(2 * math.pi * x / period)
        return [v, a / m]

    sol = solve_ivp(rhs, (0.0, float(t[-1])), [0.0, 0.0], t_eval=t, method="RK45",
                    max_step=2e-3, rtol=1e-7, atol=1e-9)
    y = sol.y[0] + (value if concealed == "sensor_offset" else 0.0)
    y = y + rng.uniform(0.0005, 0.002) * rng.standard_normal(len(t))
    y = np.round(y / COUNT_RAD) * COUNT_RAD
    off = rng.uniform(0.05, 0.2, 2) * np.where(rng.random(2) < 0.5, -1, 1)
    nominal = AxisNominal(("inertia", "viscous", "stiffness"),
                          (m * (1 + off[0]), None, k * (1 + off[1])), 0.3)
    rec = Recording.from_columns({"t_s": t, "torque_nm": u, "angle_rad": y},
                                 (("generator", "tests indep_axis"), ("seed", str(seed))))
    return IndepCase(rec, concealed, float(value), nominal,
                     2 * math.pi / period if concealed == "cogging" else 0.0)


def make_closed_loop(seed: int, asym_coulomb: float, asym_viscous: float,
                     duration_s: float = 8.0) -> tuple[Recording, AxisNominal]:
    """A drive under a stated PD position controller (force in, position out; nominal inertia,
    viscous, Coulomb), with friction that differs by direction: ``asym_coulomb`` and
    ``asym_viscous`` (per unit velocity) more while moving in the positive direction."""
    rng = np.random.default_rng(seed)
    m, c, fc = rng.uniform(0.5, 1.5), rng.uniform(0.5, 1.5), rng.uniform(0.2, 0.5)
    kp, kd = 60.0 * m, 8.0 * m
    t = np.arange(int(duration_s * RATE_HZ)) / RATE_HZ
    f = rng.uniform(0.1, 1.0, 5)
    ph = rng.uniform(0, 2 * math.pi, 5)
    ref = sum(np.sin(2 * math.pi * fi * t + p) for fi, p in zip(f, ph, strict=True)) / 3

    def rhs(ti: float, s: np.ndarray) -> list[float]:
        x, v = s
        u = kp * (float(np.interp(ti, t, ref)) - x) - kd * v
        fr = c * v + fc * math.tanh(v / 1e-3)
        if v > 0:
            fr += asym_coulomb + asym_viscous * v
        return [v, (u - fr) / m]

    sol = solve_ivp(rhs, (0.0, float(t[-1])), [0.0, 0.0], t_eval=t, method="RK45",
                    max_step=2e-3, rtol=1e-7, atol=1e-9)
    x, v = sol.y
    u = kp * (ref - x) - kd * v   # what the controller commanded (as logged)
    y = np.round((x + 3e-4 * rng.standard_normal(len(t))) / COUNT_RAD) * COUNT_RAD
    nominal = AxisNominal(("inertia", "viscous", "coulomb"), (m * 1.08, c * 0.9, fc * 1.1), 0.3)
    rec = Recording.from_columns({"t_s": t, "torque_nm": u, "angle_rad": y},
                                 (("generator", "tests indep_axis closed loop"),))
    return rec, nominal
