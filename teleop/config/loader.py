"""Generic TOML -> frozen dataclass loader with typed, ranged, documented fields.

Each config field is declared with :func:`param`, which records its documentation, unit and
allowed range in the dataclass field metadata.  :func:`build` turns a nested mapping (from
TOML) into the dataclass tree, rejecting unknown keys, wrong types and out-of-range values
with a :class:`~teleop.errors.ConfigError` that names the key and where it came from.
:func:`render_toml` writes the documented defaults (``config/default.toml`` is generated
from it and a test keeps the two equal).
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

from teleop.errors import ConfigError

T = TypeVar("T")


def param(
    default: Any,
    doc: str,
    *,
    unit: str = "",
    lo: float | None = None,
    hi: float | None = None,
    choices: tuple[str, ...] | None = None,
    size: int | None = None,
) -> Any:
    """Declare a documented config field with an optional range or set of choices.

    ``size``: for a list field, the exact number of items (one per finger, per motor...).
    """
    meta = {"doc": doc, "unit": unit, "lo": lo, "hi": hi, "choices": choices, "size": size}
    if isinstance(default, list):
        default = tuple(default)
    return dataclasses.field(default=default, metadata=meta)


def section(cls: type[T], doc: str = "") -> Any:
    """Declare a nested config section (a dataclass with all-default fields)."""
    return dataclasses.field(default_factory=cls, metadata={"doc": doc, "section": True})


def _describe(origin: str, key: str) -> str:
    """``origin: key``, escaped when either holds a newline or other unprintable character
    (a quoted TOML key can), so the error stays one line."""
    def show(text: str) -> str:
        return text if text.isprintable() else repr(text)
    return f"{show(origin)}: {show(key)}"


def _coerce(value: Any, tp: Any, key: str, origin: str) -> Any:
    """Check ``value`` against the annotated type ``tp``; return the converted value."""
    where = _describe(origin, key)
    tp_origin = typing.get_origin(tp)
    if tp_origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if value is None:
            return None
        return _coerce(value, args[0], key, origin)
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{where} must be true or false, got {value!r}")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{where} must be an integer, got {value!r}")
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{where} must be a number, got {value!r}")
        try:
            value = float(value)
        except OverflowError:  # an integer beyond the float range
            raise ConfigError(f"{where} must be finite, got an integer beyond the float "
                              "range") from None
        if not math.isfinite(value):
            raise ConfigError(f"{where} must be finite, got {value!r}")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"{where} must be a string, got {value!r}")
        return value
    if tp_origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"{where} must be a list, got {value!r}")
        elem = typing.get_args(tp)[0]
        return tuple(_coerce(v, elem, f"{key}[{i}]", origin) for i, v in enumerate(value))
    raise ConfigError(f"{where} has an unsupported type {tp!r}")  # pragma: no cover


def _check_range(value: Any, meta: Mapping[str, Any], key: str, origin: str) -> None:
    where = _describe(origin, key)
    size = meta.get("size")
    if size is not None and isinstance(value, tuple) and len(value) != size:
        raise ConfigError(f"{where} must have {size} items, got {len(value)}")
    values = value if isinstance(value, tuple) else (value,)
    for v in values:
        if v is None:
            continue
        if meta.get("choices") is not None and v not in meta["choices"]:
            opts = ", ".join(meta["choices"])
            raise ConfigError(f"{where} = {v!r} is not one of: {opts}")
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            lo, hi = meta.get("lo"), meta.get("hi")
            if lo is not None and v < lo:
                raise ConfigError(f"{where} = {v!r} is out of range (minimum {lo})")
            if hi is not None and v > hi:
                raise ConfigError(f"{where} = {v!r} is out of range (maximum {hi})")


def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def build(cls: type[T], data: Mapping[str, Any], origin: str, prefix: str = "",
          base: T | None = None) -> T:
    """Build dataclass ``cls`` from ``data`` on top of ``base`` (defaults when None)."""
    if not isinstance(data, Mapping):
        raise ConfigError(f"{_describe(origin, prefix.rstrip('.') or '<root>')} must be a table")
    hints = _hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    current = base if base is not None else cls()
    changes: dict[str, Any] = {}
    for key, value in data.items():
        full = f"{prefix}{key}"
        if key not in fields:
            raise ConfigError(f"{_describe(origin, full)} is not a known key")
        f = fields[key]
        tp = hints[key]
        if f.metadata.get("section"):
            changes[key] = build(tp, value, origin, f"{full}.", getattr(current, key))
        else:
            v = _coerce(value, tp, full, origin)
            _check_range(v, f.metadata, full, origin)
            changes[key] = v
    return dataclasses.replace(current, **changes)  # type: ignore[type-var]


def parse_override(text: str) -> tuple[list[str], Any]:
    """Parse ``a.b.c=value`` (value in TOML syntax; a bare word is taken as a string)."""
    if "=" not in text:
        raise ConfigError(f"--set {text!r}: expected key=value")
    key, raw = text.split("=", 1)
    key = key.strip()
    if not key or any(not part for part in key.split(".")):
        raise ConfigError(f"--set {text!r}: bad key")
    try:
        value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except (ValueError, RecursionError):  # TOMLDecodeError, huge integer, deep nesting
        value = raw.strip()
    return key.split("."), value


def nest(path: list[str], value: Any) -> dict[str, Any]:
    """``['a', 'b'], 1`` -> ``{'a': {'b': 1}}``."""
    out: Any = value
    for part in reversed(path):
        out = {part: out}
    return out  # type: ignore[no-any-return]


def read_toml(path: Path) -> dict[str, Any]:
    """Read a TOML file, mapping every failure to a one-line ConfigError."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{path}: config file not found") from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read config file ({exc.strerror})") from None
    except UnicodeDecodeError:
        raise ConfigError(f"{path}: not a text file") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML ({exc})") from None
    except ValueError as exc:  # e.g. an integer beyond Python's digit limit
        raise ConfigError(f"{path}: not valid TOML ({str(exc).splitlines()[0]})") from None
    except RecursionError:
        raise ConfigError(f"{path}: not valid TOML (nested too deeply)") from None


def _fmt(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, tuple):
        return "[" + ", ".join(_fmt(v) for v in value) + "]"
    if isinstance(value, float):
        return repr(value)
    return str(value)


def render_toml(obj: Any, prefix: str = "") -> str:
    """Render the dataclass tree ``obj`` as documented TOML (defaults and their meaning)."""
    scalars: list[str] = []
    tables: list[str] = []
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        meta = f.metadata
        if meta.get("section"):
            head = f"{prefix}{f.name}"
            doc = f"# {meta['doc']}\n" if meta.get("doc") else ""
            tables.append(f"\n{doc}[{head}]\n" + render_toml(value, f"{head}."))
            continue
        notes = [meta.get("doc", "")]
        if meta.get("unit"):
            notes.append(f"[{meta['unit']}]")
        rng = []
        if meta.get("lo") is not None:
            rng.append(f">= {meta['lo']}")
        if meta.get("hi") is not None:
            rng.append(f"<= {meta['hi']}")
        if rng:
            notes.append("(" + ", ".join(rng) + ")")
        if meta.get("choices"):
            notes.append("(one of: " + ", ".join(meta["choices"]) + ")")
        if value is None:
            scalars.append(f"# {' '.join(n for n in notes if n)}\n# {f.name} =  (unset)")
        else:
            scalars.append(f"# {' '.join(n for n in notes if n)}\n{f.name} = {_fmt(value)}")
    return "\n".join(scalars) + ("\n" if scalars else "") + "".join(tables)
