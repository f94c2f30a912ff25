"""Candidate effects for the axis model: applicability, fit coordinates, start grids, sentences.

Each catalog effect is fitted through one internal coordinate ``z`` (neutral at ``z = 0`` except
``actuator_gain`` and ``actuator_saturation``): series compliance is fitted as compliance
``1/k_s`` so that "absent" is a finite number.  Scales come from the data (``Scales``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from teleop.diagnose.axis_model import ROTOR_FRACTION
from teleop.diagnose.model import AxisNominal

#: Effects that only exist when there is an input.
INPUT_EFFECTS = ("dead_time", "actuator_saturation", "actuator_gain", "actuator_lag",
                 "series_compliance")

EXPLANATIONS: dict[str, str] = {
    "dead_time": "The effort acts {v:.3g} s after the command: a transport or communication "
                 "delay the nominal model does not have.",
    "coulomb_friction": "A constant friction of {v:.3g} opposes every motion (dry sliding "
                        "friction), so the motion stops short and decays linearly.",
    "asymmetric_friction": "Moving in the positive direction costs {v:.3g} more friction than "
                           "moving back (direction-dependent friction, e.g. a seal or cable).",
    "stiction": "Breaking away from rest needs {v:.3g} more than sliding (static friction with "
                "Stribeck decay), so the axis sticks at velocity reversals.",
    "backlash": "The sensor sees the load through a dead band {v:.3g} wide (backlash): the "
                "measured position stalls after each reversal while the gap is taken up.",
    "actuator_saturation": "The actuator cannot deliver more than {v:.3g}: large commands are "
                           "clipped.",
    "actuator_gain": "The actuator delivers {v:.3g} times the commanded effort "
                     "(mis-calibrated torque constant or gear ratio).",
    "actuator_lag": "The actuator effort follows the command with a {v:.3g} s time constant "
                    "(current loop or drive bandwidth).",
    "sensor_offset": "The sensor reads {v:.3g} away from the true position (zero offset).",
    "series_compliance": "A spring of stiffness {v:.3g} sits between the actuator and the load "
                         "(elastic transmission).",
    "nonlinear_stiffness": "The restoring effort grows with the cube of the position "
                           "(k3 = {v:.3g}): the spring stiffens or softens at large deflection.",
    "gravity": "A gravity moment of amplitude {v:.3g} (effort -g sin x) acts on the load.",
}


@dataclass(frozen=True, slots=True)
class Scales:
    """Typical magnitudes of the recording, used for start values and bounds."""

    effort: float          # typical effort (rms of input, or of inertia*acceleration)
    position: float        # position range
    velocity: float        # rms velocity
    umax: float            # largest |input| (0 without input)
    inertia: float         # nominal inertia estimate
    duration_s: float
    dt_s: float


def applicable(nominal: AxisNominal, has_input: bool) -> tuple[str, ...]:
    """Catalog effects that could be missing from ``nominal``."""
    out = []
    for name in ("dead_time", "coulomb_friction", "asymmetric_friction", "stiction", "backlash",
                 "actuator_saturation", "actuator_gain", "actuator_lag", "sensor_offset",
                 "series_compliance", "nonlinear_stiffness", "gravity"):
        if name in INPUT_EFFECTS and not has_input:
            continue
        if name == "coulomb_friction" and nominal.has("coulomb") and (
                nominal.value("coulomb") is None):
            continue  # a free Coulomb level already is the effect; a stated one is bounded
            # by its tolerance, and a level beyond it is the missing effect
        if name == "gravity" and nominal.has("gravity") and nominal.value("gravity") is None:
            continue  # as for Coulomb: a stated gravity level is held to its tolerance
        if name == "sensor_offset" and nominal.has("offset") and not (
                nominal.has("gravity")):
            continue  # a constant effort bias with linear springs is the same thing
        if name == "actuator_gain" and all(nominal.value(t) is None for t in nominal.terms):
            continue  # every effort term free: a gain is only a change of units
        out.append(name)
    return tuple(out)


def bounds(name: str, s: Scales) -> tuple[float, float]:
    """Bounds of the internal coordinate."""
    if name == "dead_time":
        return 0.0, min(0.5, 0.25 * s.duration_s)
    if name in ("coulomb_friction", "asymmetric_friction", "stiction"):
        return 0.0, 10.0 * s.effort
    if name == "backlash":
        return 0.0, 0.5 * s.position
    if name == "actuator_saturation":
        return 0.02 * s.umax, 1.5 * s.umax
    if name == "actuator_gain":
        return 1e-3, 100.0
    if name == "actuator_lag":
        return 0.0, min(2.0, 0.25 * s.duration_s)
    if name == "series_compliance":
        return 0.0, 1.0 / max(s.inertia * (2 * math.pi * 0.5) ** 2, 1e-12)
    return -math.inf, math.inf


def start_grid(name: str, s: Scales) -> tuple[float, ...]:
    """Start values tried for the internal coordinate (the best one seeds the local fit)."""
    if name == "dead_time":
        return tuple(d for d in (0.01, 0.03, 0.06, 0.1, 0.2) if d < bounds(name, s)[1])
    if name in ("coulomb_friction", "asymmetric_friction"):
        return (0.05 * s.effort, 0.15 * s.effort, 0.4 * s.effort)
    if name == "stiction":
        return (0.1 * s.effort, 0.3 * s.effort, 0.8 * s.effort)
    if name == "backlash":
        return (0.02 * s.position, 0.05 * s.position, 0.1 * s.position)
    if name == "actuator_saturation":
        return (0.3 * s.umax, 0.5 * s.umax, 0.7 * s.umax, 0.9 * s.umax)
    if name == "actuator_gain":
        return (0.5, 1.0, 2.0)
    if name == "actuator_lag":
        return (0.01, 0.03, 0.08, 0.2)
    if name == "sensor_offset":
        return (-0.05 * s.position, 0.05 * s.position)
    if name == "series_compliance":
        jr = ROTOR_FRACTION * s.inertia
        return tuple(1.0 / ((2 * math.pi * f) ** 2 * jr) for f in (2.0, 4.0, 8.0))
    if name == "nonlinear_stiffness":
        k3 = s.effort / max(s.position / 2, 1e-9) ** 3
        return (-0.3 * k3, 0.3 * k3)
    if name == "gravity":
        return (-0.5 * s.effort, 0.5 * s.effort)
    raise ValueError(name)


def to_effect_value(name: str, z: float, s: Scales, max_dt_s: float) -> float:
    """Catalog value of the internal coordinate (series compliance: stiffness = 1/z)."""
    if name == "series_compliance":
        ks_max = 0.5 * ROTOR_FRACTION * s.inertia / max_dt_s ** 2
        return math.inf if z <= 1.0 / ks_max else 1.0 / z
    return z


def neutral(name: str) -> float:
    """Internal coordinate meaning "absent"."""
    if name == "actuator_gain":
        return 1.0
    if name == "actuator_saturation":
        return math.inf
    return 0.0


def explanation(name: str, value: float) -> str:
    """One sentence of physics for a fitted effect."""
    return EXPLANATIONS[name].format(v=value)
