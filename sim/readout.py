"""What can be measured or drawn of a finger state: angles, load, pressures, geometry.

Also the finger's mechanical energy and tendon stretch (used by tests and tools).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sim.contact import ContactObject, sensor_pressures
from sim.params import JOINT_RATIO, FingerParams
from sim.state import FingerState
from teleop.effects import EffectSet
from teleop.frozen import fast_init


@fast_init
@dataclass(frozen=True, slots=True)
class FingerOutputs:
    """What can be measured or drawn of a finger state (angles with any sensor offset)."""

    t_s: float
    proximal_rad: float
    distal_rad: float
    motor_angle_rad: float
    motor_velocity_rad_s: float
    tendon_force_n: float
    motor_load_units: float
    pressure: tuple[float, ...]
    contact: tuple[bool, ...]
    true_proximal_rad: float
    true_motor_angle_rad: float
    joint_angle_rad: float               # driver's joint angle: measured shaft / 1.42
    points: tuple[tuple[float, float], ...]   # base, flexure joints, distal origin, tip (world)
    tendon_points: tuple[tuple[float, float], ...]  # X1, X2, Xc (world)
    tendon_point_forces_n: tuple[float, float, float]  # pseudo-transformer force magnitudes
    contact_points: tuple[tuple[float, float], ...]  # world points where contact forces act


def finger_outputs(state: FingerState, params: FingerParams, obj: ContactObject,
                   effects: EffectSet) -> FingerOutputs:
    """Measurements and drawing geometry of ``state`` (pure; no noise)."""
    p = params
    off = effects.sensor_offset
    phi = state.prox_rad
    cphi, sphi = math.cos(phi), math.sin(phi)

    def world(x: float, y: float) -> tuple[float, float]:
        return (cphi * x - sphi * y, sphi * x + cphi * y)

    pts = [(0.0, 0.0)]
    x, y, a = p.proximal_rigid_m, 0.0, 0.0
    pts.append(world(x, y))
    for s in state.flex_rad:
        a += s
        x += p.flex_segment_m * math.cos(a)
        y += p.flex_segment_m * math.sin(a)
        pts.append(world(x, y))
    ca, sa = math.cos(a), math.sin(a)

    def distal(dx: float, dy: float) -> tuple[float, float]:
        return world(x + ca * dx - sa * dy, y + sa * dx + ca * dy)

    pts.append(distal(p.distal_length_m, 0.0))
    x1 = world(*p.pin1_xy_m)
    x2 = distal(*p.pin2_xy_m)
    xc = distal(*p.tip_xy_m)
    # pseudo-transformer forces |F| = 2 F_s cos(theta), theta = half the angle between the two
    # string segments leaving the point (a straight string: theta = 90 deg, no force)
    fs = state.tendon_force_n
    base_dir = _unit(world(0.0, p.r_base_m), x1)
    d12 = _unit(x1, x2)
    d2c = _unit(x2, xc)
    f1 = fs * math.sqrt(max(0.0, 2.0 - 2.0 * (base_dir[0] * d12[0] + base_dir[1] * d12[1])))
    f2 = fs * math.sqrt(max(0.0, 2.0 - 2.0 * (d12[0] * d2c[0] + d12[1] * d2c[1])))
    pc_n, pc_x, dc_n, dc_x = state.pads
    pressure = sensor_pressures(p, pc_n, pc_x, dc_n, dc_x)
    thr = p.contact_threshold
    cpts = []
    if pc_n > 0.0:
        cpts.append(world(pc_x, p.pad_offset_m))
    if dc_n > 0.0:
        cpts.append(distal(dc_x, p.pad_offset_m))
    motor_meas = state.motor_rad + off
    return FingerOutputs(
        t_s=state.t_s, proximal_rad=phi + off, distal_rad=sum(state.flex_rad),
        motor_angle_rad=motor_meas, motor_velocity_rad_s=state.motor_vel_rad_s,
        tendon_force_n=fs, motor_load_units=state.drive[2], pressure=pressure,
        contact=tuple(v > thr for v in pressure), true_proximal_rad=phi,
        true_motor_angle_rad=state.motor_rad, joint_angle_rad=motor_meas / JOINT_RATIO,
        points=tuple(pts), tendon_points=(x1, x2, xc), tendon_point_forces_n=(f1, f2, fs),
        contact_points=tuple(cpts))


def _unit(a: tuple[float, float], b: tuple[float, float]) -> tuple[float, float]:
    """Unit vector from a towards b."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    n = math.hypot(dx, dy) or 1.0
    return (dx / n, dy / n)


def finger_energy_j(state: FingerState, params: FingerParams) -> float:
    """Mechanical energy (kinetic + springs + tendon) without contact or effects, for tests."""
    p = params
    ke = 0.5 * p.inertia_proximal_kg_m2 * state.prox_vel_rad_s ** 2
    ke += sum(0.5 * p.inertia_flex_kg_m2 * v * v for v in state.flex_vel_rad_s)
    ke += 0.5 * p.inertia_motor_kg_m2 * state.motor_vel_rad_s ** 2
    pe = 0.5 * p.k_base_nm_per_rad * (state.prox_rad + p.base_preload_rad) ** 2
    kseg = p.k_flex_segment_nm_per_rad
    pe += sum(0.5 * kseg * s * s for s in state.flex_rad)
    e = tendon_stretch_m(state, p)
    if e > 0.0:
        pe += 0.5 * p.k_tendon_n_per_m * e * e
    return ke + pe


def distal_origin(state: FingerState, p: FingerParams) -> tuple[float, float, float, float]:
    """(x, y, cos, sin) of the distal link's origin and direction in the proximal frame,
    from the flexure segment angles."""
    x, y, a = p.proximal_rigid_m, 0.0, 0.0
    for s in state.flex_rad:
        a += s
        x += p.flex_segment_m * math.cos(a)
        y += p.flex_segment_m * math.sin(a)
    return x, y, math.cos(a), math.sin(a)


def tendon_stretch_m(state: FingerState, params: FingerParams) -> float:
    """Tendon elongation beyond its slack length (eq. 4.4 path length + spool), no backlash."""
    p = params
    x, y, ca, sa = distal_origin(state, p)
    p1x, p1y = p.pin1_xy_m
    p2x, p2y = p.pin2_xy_m
    l12 = math.hypot(x + ca * p2x - sa * p2y - p1x, y + sa * p2x + ca * p2y - p1y)
    n = len(state.flex_rad)
    l12_0 = math.hypot(p.proximal_rigid_m + n * p.flex_segment_m + p2x - p1x, p2y - p1y)
    return (p.r_motor_m * state.motor_rad + (l12 - l12_0) - p.r_base_m * state.prox_rad
            - p.tendon_slack_m)
