"""A one-entry memo by identity, for pure functions of immutable arguments called every tick
with the same objects.

The controller ticks at 1 kHz, the hand's state arrives at 40 Hz: between two hand states
the per-finger pressure maxima, the forwarded contact models and the combined force are
functions of the same (frozen) message and parameters, and were worked out 25 times each.
:func:`last_result` hands back the previous result when both arguments *are* the previous
ones (``is``, not ``==``: no hashing, and an immutable object cannot have changed), so the
result is the very value the function returned for them.  Only for arguments that cannot
change (frozen dataclasses, tuples of them); the memo keeps the last pair alive.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import TypeVar

__all__ = ["last_result"]

A = TypeVar("A")
B = TypeVar("B")
R = TypeVar("R")

_MISS = object()


def last_result(fn: Callable[[A, B], R]) -> Callable[[A, B], R]:
    """``fn`` remembering its last call (see the module doc)."""
    last: list[object] = [_MISS, _MISS, _MISS]

    @functools.wraps(fn)
    def memo(a: A, b: B) -> R:
        if a is last[0] and b is last[1]:
            return last[2]  # type: ignore[return-value]
        r = fn(a, b)
        last[0], last[1], last[2] = a, b, r
        return r

    return memo
