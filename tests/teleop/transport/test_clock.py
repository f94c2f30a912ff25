"""Clocks: the virtual clock only moves forward when told; wait_until is not early."""

from __future__ import annotations

import pytest

from teleop.transport.clock import Clock, MonotonicClock, VirtualClock, wait_until


def test_virtual_clock_moves_only_forward() -> None:
    c = VirtualClock(1.0)
    assert isinstance(c, Clock) and isinstance(MonotonicClock(), Clock)
    assert c.now_s() == 1.0
    assert c.advance(0.25) == 1.25
    c.set(2.0)
    assert c.now_s() == 2.0
    with pytest.raises(ValueError):
        c.advance(-1e-3)
    with pytest.raises(ValueError):
        c.set(1.5)
    assert wait_until(c, 10.0) == 2.0  # never waits on virtual time


def test_wait_until_is_never_early() -> None:
    clock = MonotonicClock()
    for dt in (0.0, 0.0002, 0.002):
        target = clock.now_s() + dt
        assert wait_until(clock, target) >= target
        assert clock.now_s() >= target
