"""The catalog of physical effects a nominal model may leave out.

Names are fixed (DESIGN.md).  ``teleop sim --effect NAME=VALUE`` adds one to the simulated
truth; ``teleop diagnose`` fits them as augmentations of a nominal model.  Each effect has one
primary value with the meaning below; "force" means the model's actuator effort unit (N of
tendon force for the finger, N or N m for a generic axis) and "position" its output unit
(rad for the finger's motor/joint angles, the axis's own unit otherwise).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

from teleop.errors import UserInputError

#: name -> (meaning of VALUE, unit, allowed lower bound, allowed upper bound)
CATALOG: dict[str, tuple[str, str, float, float]] = {
    "dead_time": ("pure delay of the input", "s", 0.0, 5.0),
    "coulomb_friction": ("Coulomb friction level, opposing motion", "force", 0.0, math.inf),
    "asymmetric_friction": ("extra Coulomb friction acting only while moving in the positive "
                            "direction", "force", 0.0, math.inf),
    "stiction": ("breakaway (static) friction above the Coulomb level, Stribeck decay",
                 "force", 0.0, math.inf),
    "backlash": ("total dead-band width of the transmission", "position", 0.0, math.inf),
    "actuator_saturation": ("largest effort the actuator can deliver", "force", 1e-9, math.inf),
    "actuator_gain": ("multiplier on the actuator effort", "", 1e-3, 100.0),
    "actuator_lag": ("first-order time constant of the actuator effort", "s", 0.0, 10.0),
    "sensor_offset": ("constant offset added to the measured position", "position",
                      -math.inf, math.inf),
    "series_compliance": ("stiffness of a spring between actuator and load", "force/position",
                          1e-9, math.inf),
    "nonlinear_stiffness": ("cubic stiffness coefficient k3 (effort k3 x^3 opposing x)",
                            "force/position^3", -math.inf, math.inf),
    "gravity": ("gravity moment amplitude (effort -g sin(x))", "force", -math.inf, math.inf),
}

EFFECT_NAMES: tuple[str, ...] = tuple(CATALOG)


@dataclass(frozen=True, slots=True)
class EffectSet:
    """Which catalog effects act and how strongly; the neutral value means absent."""

    dead_time: float = 0.0
    coulomb_friction: float = 0.0
    asymmetric_friction: float = 0.0
    stiction: float = 0.0
    backlash: float = 0.0
    actuator_saturation: float = math.inf
    actuator_gain: float = 1.0
    actuator_lag: float = 0.0
    sensor_offset: float = 0.0
    series_compliance: float = math.inf
    nonlinear_stiffness: float = 0.0
    gravity: float = 0.0

    def active(self) -> tuple[str, ...]:
        """Names of the effects that differ from neutral."""
        neutral = EffectSet()
        return tuple(f.name for f in fields(self) if getattr(self, f.name) != getattr(neutral,
                                                                                       f.name))

    def with_effect(self, name: str, value: float) -> EffectSet:
        """A copy with effect ``name`` set to ``value`` (validated)."""
        check_effect(name, value)
        return replace(self, **{name: float(value)})


def check_effect(name: str, value: float) -> None:
    """Raise a one-line UserInputError for an unknown effect or a bad value."""
    if name not in CATALOG:
        raise UserInputError(f"unknown effect {name!r} (known: {', '.join(EFFECT_NAMES)})")
    if not math.isfinite(value):
        raise UserInputError(f"effect {name}={value}: value must be finite")
    _, _, lo, hi = CATALOG[name]
    if not lo <= value <= hi:
        raise UserInputError(f"effect {name}={value}: value out of range [{lo}, {hi}]")


def parse_effects(items: list[str] | tuple[str, ...]) -> EffectSet:
    """Parse repeated ``NAME=VALUE`` items into an EffectSet."""
    eff = EffectSet()
    seen: set[str] = set()
    for item in items:
        if "=" not in item:
            raise UserInputError(f"--effect {item!r}: expected NAME=VALUE")
        name, raw = item.split("=", 1)
        if name.strip() in seen:
            raise UserInputError(f"--effect {name.strip()} given twice")
        seen.add(name.strip())
        try:
            value = float(raw)
        except ValueError:
            raise UserInputError(f"--effect {item!r}: {raw!r} is not a number") from None
        eff = eff.with_effect(name.strip(), value)
    return eff
