"""Nominal models for ``teleop diagnose``: the axis term list and the protocol other models meet.

The diagnose pipeline fits a nominal model, then the same model augmented with catalog effects.
A model is anything that can simulate the measured output for a parameter vector and an
:class:`~teleop.effects.EffectSet` (:class:`NominalModel`).  The axis model is built in; the finger
model is adapted to the protocol in ``sim/finger_diagnose.py`` and passed in by the CLI.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from teleop.diagnose.axis_model import AXIS_TERMS
from teleop.effects import EffectSet
from teleop.errors import UserInputError

Array = NDArray[np.float64]

#: Physical bounds of each free axis term.
TERM_BOUNDS: dict[str, tuple[float, float]] = {
    "inertia": (1e-9, math.inf),
    "viscous": (0.0, math.inf),
    "stiffness": (0.0, math.inf),
    "gravity": (-math.inf, math.inf),
    "coulomb": (0.0, math.inf),
    "offset": (-math.inf, math.inf),
}


@dataclass(frozen=True, slots=True)
class AxisNominal:
    """Which axis terms the nominal model has; a given value is refined within +-tolerance."""

    terms: tuple[str, ...]
    values: tuple[float | None, ...]
    tolerance: float = 0.2

    def value(self, term: str) -> float | None:
        """The stated nominal value of ``term`` (None when free or absent)."""
        return self.values[self.terms.index(term)] if term in self.terms else None

    def has(self, term: str) -> bool:
        """Whether the nominal model has ``term``."""
        return term in self.terms

    def bounds(self, term: str) -> tuple[float, float]:
        """Fit bounds of ``term``: +-tolerance around a stated value, else physical bounds."""
        v = self.value(term)
        lo, hi = TERM_BOUNDS[term]
        if v is None:
            return lo, hi
        a, b = sorted((v * (1 - self.tolerance), v * (1 + self.tolerance)))
        if a == b:
            a, b = a - 1e-12, b + 1e-12
        return max(lo, a), min(hi, b)


def parse_nominal(text: str, tolerance: float = 0.2) -> AxisNominal:
    """Parse ``--nominal inertia=0.02,viscous,stiffness``: term names, optionally with values."""
    terms: list[str] = []
    values: list[float | None] = []
    for raw in text.split(","):
        item = raw.strip()
        if not item:
            continue
        name, _, val = item.partition("=")
        name = name.strip()
        if name not in AXIS_TERMS:
            raise UserInputError(f"--nominal: unknown term {name!r} (terms: "
                                 f"{', '.join(AXIS_TERMS)})")
        if name in terms:
            raise UserInputError(f"--nominal: term {name!r} given twice")
        value: float | None = None
        if val.strip():
            try:
                value = float(val)
            except ValueError:
                raise UserInputError(f"--nominal: {item!r}: {val!r} is not a number") from None
            if not math.isfinite(value):
                raise UserInputError(f"--nominal: {item!r}: value must be finite")
            lo, hi = TERM_BOUNDS[name]
            if not lo <= value <= hi:
                raise UserInputError(f"--nominal: {item!r}: value outside [{lo}, {hi}]")
        terms.append(name)
        values.append(value)
    if not terms:
        raise UserInputError("--nominal: no terms given")
    return AxisNominal(tuple(terms), tuple(values), tolerance)


class NominalModel(Protocol):
    """What the diagnose pipeline needs from a nominal model (output-error only)."""

    name: str

    def param_names(self) -> tuple[str, ...]:
        """Names of the refined nominal parameters."""
        ...

    def initial(self) -> Array:
        """Nominal parameter values (start of the fit)."""
        ...

    def bounds(self) -> tuple[Array, Array]:
        """Physical bounds of the parameters."""
        ...

    def candidates(self) -> tuple[str, ...]:
        """Catalog effects that apply to this model."""
        ...

    def simulate(self, theta: Array, effects: EffectSet, t_s: Array,
                 u: Array | None) -> Array:
        """The measured output at ``t_s`` for parameters ``theta`` and ``effects``."""
        ...
