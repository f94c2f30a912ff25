"""``fast_init`` (teleop/frozen.py) builds the same objects as the dataclass's own constructor.

For every class that carries it (found by walking the modules of the lockstep's hot path):
the same signature (names, kinds, defaults), the same field values for any arguments
(hypothesis: every field given, or only the required ones so the defaults and default
factories apply), still frozen; and the decorator refuses what it cannot reproduce.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import pkgutil

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from teleop.frozen import fast_init

PACKAGES = ("teleop", "services", "sim")
SKIP = ("teleop.viz", "services.launcher", "services.observer")


def _decorated() -> list[type]:
    found: dict[str, type] = {}
    for pkg_name in PACKAGES:
        pkg = importlib.import_module(pkg_name)
        for info in pkgutil.walk_packages(pkg.__path__, f"{pkg_name}."):
            if info.name.startswith(SKIP) or info.name.startswith("sim.compiled"):
                continue
            try:
                mod = importlib.import_module(info.name)
            except ImportError:  # optional dependencies (zenoh, rerun, ...)
                continue
            for v in vars(mod).values():
                if isinstance(v, type) and "__dataclass_init__" in v.__dict__:
                    found[f"{v.__module__}.{v.__qualname__}"] = v
    return [found[k] for k in sorted(found)]


CLASSES = _decorated()
VALUES = st.one_of(st.floats(allow_nan=True), st.integers(), st.booleans(),
                   st.tuples(st.floats(), st.floats()), st.none())


def test_the_hot_path_classes_are_decorated() -> None:
    names = {c.__qualname__ for c in CLASSES}
    assert {"Header", "MasterState", "ForceCommand", "HandCommand", "HandState",
            "Pending", "Delivered", "Received", "EnergyLedger", "MasterSample",
            "ControllerSample", "HandSample", "DelayAdaptState"} <= names


def _reference(cls: type, *args: object) -> object:
    obj = object.__new__(cls)
    cls.__dataclass_init__(obj, *args)  # type: ignore[attr-defined]
    return obj


def _params(init: object) -> list[tuple[str, object, int, str]]:
    """Name, kind, default (by identity: a nan default is not == itself) and annotation."""
    return [(p.name, p.kind, id(p.default), str(p.annotation))
            for p in inspect.signature(init).parameters.values()]  # type: ignore[arg-type]


def _values(obj: object) -> list[object]:
    return [getattr(obj, f.name) for f in dataclasses.fields(obj)]  # type: ignore[arg-type]


@pytest.mark.parametrize("cls", CLASSES, ids=lambda c: f"{c.__module__}.{c.__qualname__}")
@settings(max_examples=25, deadline=None)
@given(data=st.data())
def test_fast_init_matches_the_dataclass_constructor(cls: type, data: st.DataObject) -> None:
    assert _params(cls.__init__) == _params(cls.__dataclass_init__)  # type: ignore[attr-defined]
    fs = dataclasses.fields(cls)
    every = [data.draw(VALUES) for _ in fs]
    fast, ref = cls(*every), _reference(cls, *every)
    assert all(a is b for a, b in zip(_values(fast), _values(ref), strict=True))
    required = [v for v, f in zip(every, fs, strict=True)
                if f.default is dataclasses.MISSING
                and f.default_factory is dataclasses.MISSING]
    fast, ref = cls(*required), _reference(cls, *required)
    assert repr(fast) == repr(ref)
    for f, a, b in zip(fs, _values(fast), _values(ref), strict=True):
        if f.default_factory is dataclasses.MISSING:
            assert a is b
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(fast, fs[0].name, 1.0)


def test_fast_init_refuses_what_it_cannot_reproduce() -> None:
    @dataclasses.dataclass(frozen=True, slots=True)
    class Post:
        x: float

        def __post_init__(self) -> None: ...

    @dataclasses.dataclass(frozen=True, slots=True)
    class KwOnly:
        x: float = dataclasses.field(kw_only=True)

    @dataclasses.dataclass(frozen=True)
    class NoSlots:
        x: float

    @dataclasses.dataclass(slots=True)
    class Mutable:
        x: float

    for cls in (Post, KwOnly, NoSlots, Mutable):
        with pytest.raises(TypeError):
            fast_init(cls)
