"""Clocks: the services read time only through :class:`Clock`.

:class:`MonotonicClock` is the process-wide ``CLOCK_MONOTONIC`` (shared by every process on
one Linux machine, so one-way delays between local processes can be measured);
:class:`VirtualClock` only moves when advanced, for deterministic lockstep runs.
"""

from __future__ import annotations

import time
from typing import Protocol, runtime_checkable


@runtime_checkable
class Clock(Protocol):
    """Something that tells the time in seconds."""

    def now_s(self) -> float:
        """The current time [s]."""
        ...


class MonotonicClock:
    """``time.monotonic()``: system-wide on Linux, never goes back."""

    def now_s(self) -> float:
        """The current monotonic time [s]."""
        return time.monotonic()


class VirtualClock:
    """A clock that moves only when told to (lockstep simulation)."""

    def __init__(self, t0_s: float = 0.0) -> None:
        self._t_s = float(t0_s)

    def now_s(self) -> float:
        """The current virtual time [s]."""
        return self._t_s

    def advance(self, dt_s: float) -> float:
        """Move forward by ``dt_s`` >= 0; returns the new time."""
        if not dt_s >= 0.0:
            raise ValueError(f"VirtualClock.advance: dt_s must be >= 0, got {dt_s!r}")
        self._t_s += dt_s
        return self._t_s

    def set(self, t_s: float) -> None:
        """Jump to ``t_s`` (never backwards)."""
        if not t_s >= self._t_s:
            raise ValueError(f"VirtualClock.set: {t_s!r} is before now ({self._t_s!r})")
        self._t_s = float(t_s)


def wait_until(clock: Clock, t_s: float, spin_s: float = 300e-6) -> float:
    """Sleep, then spin for the last ``spin_s``, until ``clock.now_s() >= t_s``; returns now.

    Python's ``time.sleep`` overshoots by ~50-100 us; the spin makes a 1 kHz loop exact.
    A :class:`VirtualClock` is not waited for (returns its time at once).
    """
    if isinstance(clock, VirtualClock):
        return clock.now_s()
    now = clock.now_s()
    remaining = t_s - now
    if remaining > spin_s:
        time.sleep(remaining - spin_s)
    now = clock.now_s()
    while now < t_s:
        now = clock.now_s()
    return now
