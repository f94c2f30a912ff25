"""A faster constructor for the frozen, slotted dataclasses built on every tick.

A frozen dataclass's generated ``__init__`` sets each field with
``object.__setattr__(self, "name", value)``: a global and an attribute lookup and a generic
call per field, about 0.25 us each.  The lockstep builds some 35 such objects (170 fields)
per simulated millisecond (headers, messages, delay-line entries, ledgers, controller states,
samples), so that alone was several per cent of its time.  :func:`fast_init` replaces the
generated ``__init__`` of such a class by one with the same parameters and defaults that
stores each argument through its slot's descriptor (``Cls.name.__set__``), which is what
``object.__setattr__`` ends up doing, without the lookups.  Nothing else changes: the class is
still the frozen dataclass (assignment raises ``FrozenInstanceError``; ``__eq__``,
``__hash__``, ``__repr__``, ``replace`` and ``fields`` as before), and an instance holds the
same values as one built by the generated constructor, which stays available as
``cls.__dataclass_init__`` (``tests/teleop/test_frozen.py`` holds the two to each other).

Usage::

    @fast_init
    @dataclass(frozen=True, slots=True)
    class Header:
        seq: int
        t_s: float

Plain fields, with a default or a ``default_factory`` (called per instance when the argument
is left out, as the dataclass does), are supported; anything else (``__post_init__``,
``InitVar``, ``init=False``, ``kw_only``) raises ``TypeError`` when the class is decorated, so
a decorated class never silently loses a dataclass feature.
"""

from __future__ import annotations

import dataclasses
from typing import TypeVar

__all__ = ["fast_init"]

T = TypeVar("T", bound=type)

_PREFIX = "_fast_init_"

#: the default of a ``default_factory`` parameter: the dataclass's own marker (shown as
#: ``<factory>``), so the signature is the generated constructor's
_UNSET = dataclasses._HAS_DEFAULT_FACTORY  # type: ignore[attr-defined]


def _check(cls: type) -> list[dataclasses.Field[object]]:
    if not dataclasses.is_dataclass(cls):
        raise TypeError(f"{cls.__name__} is not a dataclass")
    if not cls.__dataclass_params__.frozen or "__slots__" not in cls.__dict__:  # type: ignore[attr-defined]
        raise TypeError(f"{cls.__name__}: fast_init needs frozen=True, slots=True")
    if hasattr(cls, "__post_init__"):
        raise TypeError(f"{cls.__name__}: fast_init does not call __post_init__")
    declared = cls.__dataclass_fields__.values()  # type: ignore[attr-defined]
    if any(f._field_type is not dataclasses._FIELD for f in declared):  # type: ignore[attr-defined]
        raise TypeError(f"{cls.__name__}: fast_init supports plain fields only")
    fs = list(dataclasses.fields(cls))
    for f in fs:
        if not f.init or f.kw_only:
            raise TypeError(f"{cls.__name__}.{f.name}: fast_init supports plain fields only")
    return fs


def fast_init(cls: T) -> T:
    """``cls`` with a descriptor-setting ``__init__`` (see the module docstring)."""
    fs = _check(cls)
    namespace: dict[str, object] = {f"{_PREFIX}unset": _UNSET}
    params: list[str] = []
    body: list[str] = []
    for f in fs:
        namespace[f"{_PREFIX}set_{f.name}"] = cls.__dict__[f.name].__set__
        value = f.name
        if f.default_factory is not dataclasses.MISSING:
            namespace[f"{_PREFIX}factory_{f.name}"] = f.default_factory
            params.append(f"{f.name}={_PREFIX}unset")
            value = (f"{_PREFIX}factory_{f.name}() if {f.name} is {_PREFIX}unset "
                     f"else {f.name}")
        elif f.default is dataclasses.MISSING:
            params.append(f.name)
        else:
            namespace[f"{_PREFIX}default_{f.name}"] = f.default
            params.append(f"{f.name}={_PREFIX}default_{f.name}")
        body.append(f"    {_PREFIX}set_{f.name}(self, {value})\n")
    src = (f"def __init__(self, {', '.join(params)}):\n" if params else "def __init__(self):\n")
    exec(src + ("".join(body) or "    pass\n"), namespace)  # noqa: S102 (generated, as dataclasses does)
    init = namespace["__init__"]
    reference = cls.__init__  # type: ignore[misc]
    init.__qualname__ = f"{cls.__qualname__}.__init__"  # type: ignore[attr-defined]
    init.__annotations__ = dict(reference.__annotations__)  # type: ignore[attr-defined]
    init.__doc__ = reference.__doc__  # type: ignore[attr-defined]
    cls.__dataclass_init__ = reference  # type: ignore[attr-defined]
    cls.__init__ = init  # type: ignore[misc]
    return cls
