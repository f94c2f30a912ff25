"""Refined finger parameters and found effects as a TOML file (closing the diagnose loop).

``teleop diagnose REC --model finger --write-params M.toml`` writes what it refined and found;
``teleop sim ... --set hand.sim.model=M.toml`` and the simulated hand (``hand.sim.model`` in the
config) load it, so the simulation then has the physics the recording showed::

    # teleop diagnose --write-params, from runs/a/hand.csv
    [finger]                      # FingerParams fields (sim/params.py), SI / servo units
    units_per_n = 4.87
    motor_coulomb_units = 20.3
    k_base_nm_per_rad = 0.0641
    speed_law_fraction = 0.62

    [effects]                     # catalog effects (teleop/effects.py)
    dead_time = 0.0913

A position-periodic shaft force the diagnosis found outside the catalog is written under
``[finger]`` as ``shaft_ripple_sin_n``, ``shaft_ripple_cos_n`` and ``shaft_ripple_per_rad``.

A file that names an unknown field or effect, a value that is not a finite number, or a share
(``speed_law_fraction``) outside [0, 1], stops with one line naming the file and the key
(exit 2).
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import fields, replace
from pathlib import Path

from sim.params import FingerParams, default_finger_params
from teleop.effects import EffectSet
from teleop.errors import UserInputError

#: [finger] keys that are shares, refused outside [0, 1]
FRACTIONS = ("speed_law_fraction",)
_FLOAT_FIELDS = tuple(f.name for f in fields(FingerParams) if f.type in ("float", float))


def write_model(path: Path, params: dict[str, float], effects: dict[str, float],
                source: str) -> None:
    """Write refined ``params`` (FingerParams field -> value) and ``effects`` as TOML."""
    for k in params:
        if k not in _FLOAT_FIELDS:
            raise ValueError(f"not a FingerParams number: {k}")
    lines = [f"# teleop diagnose --write-params, from {source}", "[finger]"]
    lines += [f"{k} = {float(v)!r}" for k, v in params.items()]
    lines += ["", "[effects]"]
    lines += [f"{k} = {float(v)!r}" for k, v in effects.items()]
    try:
        path.write_text("\n".join(lines) + "\n")
    except OSError as exc:
        raise UserInputError(f"{path}: cannot write ({exc.strerror})") from None


def load_model(path: str | Path, base: FingerParams | None = None
               ) -> tuple[FingerParams, EffectSet]:
    """The finger parameters (``base`` or the calibrated defaults, with the file's fields) and
    the effects a model file holds."""
    p = Path(path)
    try:
        doc = tomllib.loads(p.read_text())
    except OSError as exc:
        raise UserInputError(f"{p}: cannot read the finger model ({exc.strerror})") from None
    except tomllib.TOMLDecodeError as exc:
        raise UserInputError(f"{p}: not a TOML finger model ({exc})") from None
    for key in doc:
        if key not in ("finger", "effects"):
            raise UserInputError(f"{p}: unknown section [{key}] (expected [finger], [effects])")
    fp = base or default_finger_params()
    values: dict[str, float] = {}
    for key, v in doc.get("finger", {}).items():
        if key not in _FLOAT_FIELDS:
            raise UserInputError(f"{p}: [finger] {key}: not a finger parameter (sim/params.py)")
        values[key] = _number(p, "finger", key, v)
        if key in FRACTIONS and not 0.0 <= values[key] <= 1.0:
            raise UserInputError(f"{p}: [finger] {key} = {v!r} is outside [0, 1]")
    eff = EffectSet()
    for key, v in doc.get("effects", {}).items():
        try:
            eff = eff.with_effect(key, _number(p, "effects", key, v))
        except UserInputError as exc:
            raise UserInputError(f"{p}: [effects] {exc}") from None
    return replace(fp, **values), eff


def _number(p: Path, section: str, key: str, v: object) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(float(v)):
        raise UserInputError(f"{p}: [{section}] {key} = {v!r} is not a finite number")
    return float(v)
