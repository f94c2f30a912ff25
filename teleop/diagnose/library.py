"""A typed library of effort terms outside the catalog, for physics the catalog does not have.

Every term is an effort added to the load equation, ``J x'' = ... + c phi(x, v, u)``, with one
coefficient ``c`` and at most one structural constant (a wavenumber or a delay):

==========  ====================  ==================================================
kind        phi                   physics it stands for
==========  ====================  ==================================================
``sin``     sin(w x)              position-periodic effort (cogging, detent, eccentric
``cos``     cos(w x)              load); ``sin`` and ``cos`` of one ``w`` come as a pair
``vabsv``   v |v|                 quadratic (turbulent / air) drag
``v3``      v^3                   cubic damping
``v2``      v^2                   direction-dependent quadratic drag
``x2``      x^2                   asymmetric spring
``x3``      x^3                   stiffening / softening spring
``udelay``  u(t - d)              a delayed share of the input (a second path)
==========  ====================  ==================================================

A term is named ``term:KIND:CONST`` (e.g. ``term:sin:25.13``) wherever a fit carries it, so its
coefficient travels through every fit with the other parameters.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

STATE_KINDS = ("sin", "cos", "vabsv", "v3", "v2", "x2", "x3")
KINDS = (*STATE_KINDS, "udelay")
PREFIX = "term:"
#: A fitted wavenumber of the sin/cos pair first named with wavenumber W: ``wave:W``.
WAVE = "wave:"
#: The engine's candidate name of a position-periodic sin/cos pair whose wavenumber a
#: simulated model scans (:mod:`teleop.diagnose.select_sim_terms`)
PERIODIC = "term:periodic"


@dataclass(frozen=True, slots=True)
class Term:
    """One library term: its kind and structural constant (wavenumber in 1/position unit, or
    delay in s; 0 when the kind has none)."""

    kind: str
    const: float = 0.0

    @property
    def key(self) -> str:
        """Its parameter name in a fit (``term:KIND:CONST``)."""
        return f"{PREFIX}{self.kind}:{self.const:.6g}"

    @staticmethod
    def is_key(name: str) -> bool:
        """Whether a fit's parameter name is a library term's (not a catalog effect's)."""
        return name.startswith(PREFIX)

    @staticmethod
    def parse(key: str) -> Term:
        """The term a parameter name stands for."""
        kind, _, const = key[len(PREFIX):].partition(":")
        if kind not in KINDS:
            raise ValueError(f"unknown library term {key!r}")
        return Term(kind, float(const or 0.0))


def column(term: Term, t: Array, x: Array, v: Array, u: Array | None) -> Array:
    """``phi`` of ``term`` on sampled signals."""
    k, w = term.kind, term.const
    if k == "sin":
        return np.sin(w * x)
    if k == "cos":
        return np.cos(w * x)
    if k == "vabsv":
        return v * np.abs(v)
    if k == "v3":
        return v ** 3
    if k == "v2":
        return v ** 2
    if k == "x2":
        return x ** 2
    if k == "x3":
        return x ** 3
    if u is None:
        return np.zeros_like(x)
    return np.interp(t - w, t, u, left=u[0])


def resolve(vals: dict[str, float]) -> tuple[tuple[str, float], ...]:
    """(key, coefficient) of the library terms among fit parameters ``vals``, a sin/cos pair
    keyed by the wavenumber its ``wave:`` parameter now has."""
    out = []
    for k, c in vals.items():
        if k.startswith(PREFIX):
            t = Term.parse(k)
            w = vals.get(f"{WAVE}{t.const:.6g}") if t.kind in ("sin", "cos") else None
            out.append((Term(t.kind, w).key if w is not None else k, c))
    return tuple(out)


def state_terms(coefs: dict[str, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The state terms among ``coefs`` (keys ``term:...``) for the simulation kernel
    (:mod:`teleop.diagnose.axis_kernel`): (kind codes, index in :data:`STATE_KINDS`;
    coefficients; wavenumbers, 0 for kinds without one), in the order of ``coefs``."""
    parts = [(Term.parse(k), c) for k, c in coefs.items()
             if k.startswith(PREFIX) and Term.parse(k).kind in STATE_KINDS and c != 0.0]
    return (np.array([STATE_KINDS.index(t.kind) for t, _ in parts], dtype=np.int64),
            np.array([c for _, c in parts], dtype=np.float64),
            np.array([t.const for t, _ in parts], dtype=np.float64))


def input_terms(coefs: dict[str, float]) -> tuple[tuple[float, float], ...]:
    """(delay, coefficient) of the delayed-input terms among ``coefs``."""
    out = []
    for k, c in coefs.items():
        if k.startswith(PREFIX):
            term = Term.parse(k)
            if term.kind == "udelay":
                out.append((term.const, c))
    return tuple(out)


def equation(coefs: dict[str, float], effort_unit: str, pos_unit: str) -> str:
    """The added terms as one equation with units, e.g.
    ``effort += 0.15 N m * sin(25.1 rad^-1 * x) - ...``."""
    vel = f"{pos_unit}/s"
    parts = []
    for k, c in coefs.items():
        t = Term.parse(k)
        w = t.const
        phi, unit = {
            "sin": (f"sin({w:.4g} {pos_unit}^-1 * x)", effort_unit),
            "cos": (f"cos({w:.4g} {pos_unit}^-1 * x)", effort_unit),
            "vabsv": ("v*|v|", f"{effort_unit} s^2/{pos_unit}^2"),
            "v3": ("v^3", f"{effort_unit} s^3/{pos_unit}^3"),
            "v2": ("v^2", f"{effort_unit} s^2/{pos_unit}^2"),
            "x2": ("x^2", f"{effort_unit}/{pos_unit}^2"),
            "x3": ("x^3", f"{effort_unit}/{pos_unit}^3"),
            "udelay": (f"u(t - {w:.4g} s)", "1"),
        }[t.kind]
        parts.append(f"{'-' if c < 0 else '+'} {abs(c):.4g} [{unit}] * {phi}")
    body = " ".join(parts).lstrip("+ ")
    return (f"effort [{effort_unit}] += {body}   (x in {pos_unit}, v in {vel})"
            if parts else "")


def units(column_name: str | None, fallback: str) -> str:
    """A unit from a column name's suffix (``torque_nm`` -> N m), else ``fallback``."""
    if not column_name:
        return fallback
    for suffix, unit in (("_nm", "N m"), ("_n", "N"), ("_rad", "rad"), ("_deg", "deg"),
                         ("_mm", "mm"), ("_m", "m"), ("_units", "units")):
        if column_name.endswith(suffix):
            return unit
    return fallback
