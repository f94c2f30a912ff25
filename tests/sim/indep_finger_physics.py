"""Independent physics of one ReFlex finger for the diagnose proof (not :mod:`sim.finger`).

Written from the seed report's structure and numbers (chapter 4, Tables 4.1/4.2) and the
hardware notes, with its own lumping, friction law and integrator:

* three bodies: the MX-28 output shaft (reflected inertia ``inertia_motor``), the proximal link
  on the base joint (a torsional spring preloaded against the open stop, so the finger rests at
  0 and lifts only above ~7 N of tendon force), and the distal link on the urethane flexure,
  lumped into ONE torsional spring-damper (the project splits it into four series segments);
* the tendon is a one-way spring-damper (it only pulls) wound on the spool (radius
  ``r_motor``) and routed with CONSTANT moment arms over the base joint (``r_base`` = 1.42
  r_motor, the driver's joint ratio) and the flexure (``r_distal``, the 8 mm pin height);
  the project computes the path from the pin geometry instead;
* the motor's speed-dependent friction is a power law ``A |w|^p`` fitted here to Table 4.1's
  terminal speeds (inputs 50/100/200 units, minus the Coulomb level): the project interpolates a
  viscous coefficient that depends on the EFFORT instead.  Both reproduce Table 4.1 at steady
  state and differ in transients and in position mode (a physically justified mismatch: the
  report gives only those three points);
* joint stops are stiff, damped penalty springs (the project uses inelastic stops);
* the servo: force mode applies the commanded effort; position mode is a P controller on the
  measured shaft angle (``kp`` units/rad), clamped at 1023 units; 5 units per N of tendon force.

Integrated with a fixed-step classical Runge-Kutta (RK4) written here; the backlash play and the
delay line are updated between steps (discrete-time operators, documented where they are).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import optimize

Array = NDArray[np.float64]

# Table 4.1: (input units, terminal shaft speed rad/s) pulling an unloaded string
TABLE_4_1 = ((50.0, 0.06733), (100.0, 0.1781), (200.0, 0.4240))
# Table 4.2, model column, lifted rows: (tendon force N, proximal angle rad)
TABLE_4_2_LIFTED = ((15.7, 2.407), (9.8, 0.767))


def _power_law(coulomb_units: float, w0_rad_s: float) -> tuple[float, float]:
    """(A, p) of the regularised law ``u - u_c = A ((w + w0)^p - w0^p)`` through Table 4.1
    (least squares on the log of the friction, so each point weighs the same)."""
    w = np.array([wi for _, wi in TABLE_4_1])
    y = np.log([u - coulomb_units for u, _ in TABLE_4_1])

    def resid(x: Array) -> Array:
        return x[0] + np.log((w + w0_rad_s) ** x[1] - w0_rad_s ** x[1]) - y

    p0, ln_a0 = np.polyfit(np.log(w), y, 1)
    fit = optimize.least_squares(resid, [ln_a0, p0], bounds=([-np.inf, 0.1], [np.inf, 2.0]))
    return float(math.exp(fit.x[0])), float(fit.x[1])


def _base_spring(r_base_m: float) -> tuple[float, float]:
    """(stiffness N m/rad, preload rad) through the two lifted Table 4.2 rows."""
    (f1, a1), (f2, a2) = TABLE_4_2_LIFTED
    rad_per_n = (a1 - a2) / (f1 - f2)
    return r_base_m / rad_per_n, f1 * rad_per_n - a1


R_MOTOR_M = 0.01222
R_BASE_M = 1.42 * R_MOTOR_M
_K_BASE, _PRELOAD = _base_spring(R_BASE_M)
FRICTION_W0_RAD_S = 0.01
_A, _P = _power_law(5.0, FRICTION_W0_RAD_S)


@dataclass(frozen=True, slots=True)
class FingerTruth:
    """The true finger of one generated case (SI; ``*_units`` are servo units)."""

    units_per_n: float = 5.0
    motor_coulomb_units: float = 5.0
    k_base_nm_per_rad: float = _K_BASE
    base_preload_rad: float = _PRELOAD
    k_flex_nm_per_rad: float = 0.30
    inertia_motor_kg_m2: float = 3.0e-3
    inertia_proximal_kg_m2: float = 1.9e-4
    inertia_distal_kg_m2: float = 2.0e-5
    c_base_nm_s_per_rad: float = 1.0e-3
    c_flex_nm_s_per_rad: float = 0.75e-3   # four 3e-3 segments in series
    r_motor_m: float = R_MOTOR_M
    r_base_m: float = R_BASE_M
    r_distal_m: float = 0.008
    k_tendon_n_per_m: float = 2.0e4
    c_tendon_n_s_per_m: float = 20.0
    tendon_slack_m: float = 0.0005
    friction_a_units: float = _A          # speed friction u = A |w|^p (w in rad/s)
    friction_p: float = _P
    friction_w0_rad_s: float = FRICTION_W0_RAD_S  # regularises the power law's infinite slope at 0
    coulomb_w_rad_s: float = 0.005        # tanh width of the Coulomb sign
    friction_law: str = "speed"           # "effort": Table 4.1 read as a viscous coefficient
    #                                       that depends on the effort (only to measure how
    #                                       much of the model gap the friction law makes)
    kp_units_per_rad: float = 1000.0
    max_units: float = 1023.0
    proximal_limits_rad: tuple[float, float] = (0.0, 2.8)
    distal_limits_rad: tuple[float, float] = (-0.2, 1.8)
    k_stop_nm_per_rad: float = 200.0
    c_stop_nm_s_per_rad: float = 0.2


@dataclass(frozen=True, slots=True)
class Effects:
    """Concealed physics (names and units as the catalog's: forces N of tendon force, angles
    rad of motor shaft)."""

    coulomb_friction_n: float = 0.0
    actuator_lag_s: float = 0.0
    dead_time_s: float = 0.0
    sensor_offset_rad: float = 0.0
    backlash_rad: float = 0.0
    actuator_gain: float = 1.0
    cogging_n: float = 0.0               # outside the catalog: A sin(2 pi theta / period)
    cogging_period_rad: float = 0.2


@dataclass(frozen=True, slots=True)
class Command:
    """The servo command at one instant: ``mode`` "force" (``units``) or "position"
    (``goal_rad`` of shaft)."""

    mode: str
    units: float = 0.0
    goal_rad: float = 0.0


# state: motor angle, motor speed, proximal, proximal speed, distal, distal speed, lagged effort
N_STATE = 7


def _stop(x: float, v: float, lo: float, hi: float, p: FingerTruth) -> float:
    if x < lo:
        return -p.k_stop_nm_per_rad * (x - lo) - p.c_stop_nm_s_per_rad * min(v, 0.0)
    if x > hi:
        return -p.k_stop_nm_per_rad * (x - hi) - p.c_stop_nm_s_per_rad * max(v, 0.0)
    return 0.0


def tension_n(s: list[float] | Array, spool_rad: float, p: FingerTruth) -> float:
    """Tendon tension (one-way spring-damper; the spool at ``spool_rad``)."""
    stretch = (p.r_motor_m * spool_rad - p.r_base_m * s[2] - p.r_distal_m * s[4]
               - p.tendon_slack_m)
    if stretch <= 0.0:
        return 0.0
    rate = p.r_motor_m * s[1] - p.r_base_m * s[3] - p.r_distal_m * s[5]
    return max(0.0, p.k_tendon_n_per_m * stretch + p.c_tendon_n_s_per_m * rate)


def effort_target(cmd: Command, measured_rad: float, p: FingerTruth, e: Effects) -> float:
    """The effort (units) the servo produces before the lag: force command or P control on
    the measured angle, clamped, times the concealed gain."""
    u = cmd.units if cmd.mode == "force" else p.kp_units_per_rad * (cmd.goal_rad - measured_rad)
    u = min(max(u, -p.max_units), p.max_units)
    return u * e.actuator_gain


def _effort_damping(effort_units: float, coulomb_units: float) -> float:
    """Units per rad/s at this effort: log-log through (u - u_c) / speed of Table 4.1."""
    u = min(max(abs(effort_units), 20.0), 1023.0)
    xs = [math.log(ui) for ui, _ in TABLE_4_1]
    ys = [math.log((ui - coulomb_units) / wi) for ui, wi in TABLE_4_1]
    i = 0 if math.log(u) < xs[1] else 1
    slope = (ys[i + 1] - ys[i]) / (xs[i + 1] - xs[i])
    return math.exp(ys[i] + slope * (math.log(u) - xs[i]))


def motor_friction_nm(w: float, p: FingerTruth, e: Effects, effort_units: float = 0.0
                      ) -> float:
    """Friction torque on the shaft (opposing ``w``): Coulomb (tanh) plus the power law (or,
    ``friction_law="effort"``, an effort-dependent viscous coefficient)."""
    coulomb_n = p.motor_coulomb_units / p.units_per_n + e.coulomb_friction_n
    if p.friction_law == "effort":
        speed_units = _effort_damping(effort_units, p.motor_coulomb_units) * abs(w)
    else:
        speed_units = p.friction_a_units * ((abs(w) + p.friction_w0_rad_s) ** p.friction_p
                                            - p.friction_w0_rad_s ** p.friction_p)
    f_n = coulomb_n * math.tanh(w / p.coulomb_w_rad_s) + math.copysign(
        speed_units / p.units_per_n, w)
    return f_n * p.r_motor_m


def derivative(s: list[float], cmd: Command, spool_offset_rad: float, p: FingerTruth,
               e: Effects) -> list[float]:
    """d(state)/dt; the spool is at shaft angle minus ``spool_offset_rad`` (backlash)."""
    th, w, phi, v_phi, psi, v_psi, lagged = s
    target = effort_target(cmd, th + e.sensor_offset_rad, p, e)
    if e.actuator_lag_s > 0.0:
        effort = lagged
        d_lag = (target - lagged) / e.actuator_lag_s
    else:
        effort, d_lag = target, 0.0
    t_n = tension_n(s, th - spool_offset_rad, p)
    torque_m = (effort / p.units_per_n - t_n) * p.r_motor_m - motor_friction_nm(w, p, e, effort)
    if e.cogging_n:
        torque_m -= e.cogging_n * p.r_motor_m * math.sin(2 * math.pi * th / e.cogging_period_rad)
    lo, hi = p.proximal_limits_rad
    torque_p = (t_n * p.r_base_m - p.k_base_nm_per_rad * (phi + p.base_preload_rad)
                - p.c_base_nm_s_per_rad * v_phi + _stop(phi, v_phi, lo, hi, p))
    lo, hi = p.distal_limits_rad
    torque_d = (t_n * p.r_distal_m - p.k_flex_nm_per_rad * psi - p.c_flex_nm_s_per_rad * v_psi
                + _stop(psi, v_psi, lo, hi, p))
    return [w, torque_m / p.inertia_motor_kg_m2, v_phi, torque_p / p.inertia_proximal_kg_m2,
            v_psi, torque_d / p.inertia_distal_kg_m2, d_lag]


def rk4_step(s: list[float], cmd: Command, spool_offset_rad: float, p: FingerTruth,
             e: Effects, h: float) -> list[float]:
    """One classical Runge-Kutta step (command and spool offset held over the step)."""
    k1 = derivative(s, cmd, spool_offset_rad, p, e)
    k2 = derivative([a + 0.5 * h * b for a, b in zip(s, k1, strict=True)], cmd,
                    spool_offset_rad, p, e)
    k3 = derivative([a + 0.5 * h * b for a, b in zip(s, k2, strict=True)], cmd,
                    spool_offset_rad, p, e)
    k4 = derivative([a + h * b for a, b in zip(s, k3, strict=True)], cmd, spool_offset_rad, p, e)
    return [a + h / 6.0 * (b1 + 2 * b2 + 2 * b3 + b4)
            for a, b1, b2, b3, b4 in zip(s, k1, k2, k3, k4, strict=True)]


def _play(spool_rad: float, s: list[float], p: FingerTruth, width: float) -> float:
    """Backlash as a play operator on the massless spool, updated between steps: the spool
    stays where it was unless the shaft's +-width/2 band pushes it; a tendon that would be
    taut with the spool at the band's trailing end pulls it there."""
    th = s[0]
    if width <= 0.0:
        return th
    if tension_n(s, th - 0.5 * width, p) > 0.0:
        return th - 0.5 * width
    return min(max(spool_rad, th - 0.5 * width), th + 0.5 * width)


@dataclass(frozen=True, slots=True)
class Trajectory:
    """Sampled true states (no sensor effects) and the effort each sample was commanded."""

    t_s: Array
    motor_rad: Array
    motor_vel_rad_s: Array
    proximal_rad: Array
    distal_rad: Array
    tendon_n: Array
    effort_units: Array


def simulate(command_at: Callable[[float], Command], duration_s: float, rate_hz: float,
             p: FingerTruth, e: Effects, h_s: float = 5e-4) -> Trajectory:
    """Integrate from rest (finger open, tendon slack) and sample at ``rate_hz``.  The dead
    time is applied to the command: at time t the servo executes ``command_at(t - dead)``
    (the command before 0 is force 0)."""
    every = max(1, round(1.0 / (rate_hz * h_s)))
    n = int(round(duration_s * rate_hz))
    s = [0.0] * N_STATE
    spool = 0.0
    rows = []
    for k in range(n * every):
        t = k * h_s
        tc = t - e.dead_time_s
        cmd = command_at(tc) if tc >= 0.0 else Command("force", 0.0)
        if k % every == 0:
            eff = s[6] if e.actuator_lag_s > 0.0 else effort_target(
                cmd, s[0] + e.sensor_offset_rad, p, e)
            rows.append((t, s[0], s[1], s[2], s[4], tension_n(s, spool, p), eff))
        s = rk4_step(s, cmd, s[0] - spool, p, e, h_s)
        spool = _play(spool, s, p, e.backlash_rad)
    a = np.asarray(rows, float)
    return Trajectory(a[:, 0], a[:, 1], a[:, 2], a[:, 3], a[:, 4], a[:, 5], a[:, 6])


def static_angles(p: FingerTruth, force_units: float) -> tuple[float, float]:
    """Hand-derived equilibrium (proximal, distal rad) under a constant force command with no
    Coulomb friction (the speed law is zero at rest): the tendon carries u / units_per_n; the
    base spring balances T r_base above its preload, the flexure T r_distal."""
    t = force_units / p.units_per_n
    prox = max(0.0, t * p.r_base_m / p.k_base_nm_per_rad - p.base_preload_rad)
    return prox, t * p.r_distal_m / p.k_flex_nm_per_rad
