"""RateLoop: exact ticks on a virtual clock, 1 kHz on the real one."""

from __future__ import annotations

import numpy as np
import pytest

from services.bench import loop_summary
from services.runtime import RateLoop
from teleop.transport.clock import MonotonicClock, VirtualClock


def test_virtual_clock_ticks_at_every_deadline() -> None:
    clock = VirtualClock(10.0)
    seen: list[float] = []
    loop = RateLoop(40.0, clock=clock)
    stats = loop.run(seen.append, duration_s=1.0)
    assert stats.ticks == 40
    assert np.allclose(np.diff(seen), 0.025)
    assert seen[0] == 10.0
    assert np.all(stats.lateness_s == 0.0)


def test_stop_from_tick_ends_the_loop() -> None:
    loop = RateLoop(1000.0, clock=VirtualClock())
    n = []

    def tick(t: float) -> None:
        n.append(t)
        if len(n) == 5:
            loop.stop()

    assert loop.run(tick).ticks == 5


def test_long_stall_skips_deadlines_instead_of_bursting() -> None:
    clock = VirtualClock()
    loop = RateLoop(1000.0, clock=clock, catchup_periods=3)
    times: list[float] = []

    def tick(t: float) -> None:
        times.append(t)
        if len(times) == 2:
            clock.advance(0.0105)  # a 10.5 ms stall

    stats = loop.run(tick, duration_s=0.02)
    assert stats.skipped == 9  # deadlines 2..10 ms dropped, 11 ms ticked late
    assert all(b > a for a, b in zip(times, times[1:], strict=False))
    # the percentiles re-base after the stall, the max and the stall count do not hide it
    fig = stats.figures("x")
    assert fig["x_lateness_p99_us"] <= 1000.0
    assert fig["x_stalls"] == 1.0
    assert fig["x_lateness_max_us"] == pytest.approx(9500.0)  # from the 2 ms deadline
    assert fig["x_stall_lateness_max_us"] == pytest.approx(9500.0)
    assert fig["x_lateness_max_us"] >= fig["x_lateness_p99_us"] >= fig["x_lateness_p50_us"]
    assert fig["x_tick_max_us"] >= fig["x_tick_p99_us"]


def test_timing_callback_gets_every_tick_and_the_loop_keeps_none() -> None:
    clock = VirtualClock()
    loop = RateLoop(1000.0, clock=clock, catchup_periods=3)
    got: list[tuple[float, float, float]] = []
    n = [0]

    def tick(t: float) -> None:
        n[0] += 1
        if n[0] == 2:
            clock.advance(0.0105)

    stats = loop.run(tick, duration_s=0.02, timing=lambda *a: got.append(a))
    assert stats.ticks == len(got) == n[0] and stats.lateness_s.size == 0  # nothing kept
    assert stats.skipped == 9 and stats.stall_ticks == (2,)
    stalls = [s for _, _, s in got if s > 0]
    assert stalls == [pytest.approx(0.0095)]  # the true lateness of the stall, once
    assert got[2][1] == pytest.approx(0.0005)  # re-based lateness of that tick


def test_without_stalls_the_max_is_the_largest_tick_lateness() -> None:
    stats = RateLoop(40.0, clock=VirtualClock()).run(lambda t: None, duration_s=1.0)
    fig = stats.figures("y")
    assert fig["y_stalls"] == 0.0 and fig["y_lateness_max_us"] == 0.0
    assert fig["y_stall_lateness_max_us"] == 0.0


def test_loop_bench_summary_puts_max_and_stalls_beside_the_p99() -> None:
    figures: dict[str, float] = {}
    for role, (p50, p99, top, stalls) in {"master": (20.0, 300.0, 25_000.0, 2.0),
                                           "controller": (30.0, 400.0, 900.0, 0.0),
                                           "hand": (10.0, 50.0, 40_000.0, 1.0)}.items():
        figures |= {f"{role}_rate_hz": 1000.0, f"{role}_lateness_p50_us": p50,
                    f"{role}_lateness_p99_us": p99, f"{role}_lateness_max_us": top,
                    f"{role}_stalls": stalls}
    s = loop_summary(figures)
    assert s["lateness_p99_us"] == 400.0  # worst of master and controller (the floor's)
    assert s["lateness_max_us"] == 40_000.0 and s["stalls"] == 3.0
    assert s["lateness_max_us"] >= s["lateness_p99_us"]
    assert s["floor_p99_ok"] == 1.0  # rate and p99 alone would pass ...
    assert s["floor_ok"] == 0.0  # ... but the master's 25 ms stall trips the watchdogs
    calm = figures | {"master_lateness_max_us": 900.0, "hand_lateness_max_us": 90_000.0}
    assert loop_summary(calm)["floor_ok"] == 1.0  # (the 40 Hz hand is not floored)
    assert loop_summary(calm | {"controller_lateness_max_us": 20_001.0})["floor_ok"] == 0.0


@pytest.mark.slow
def test_real_clock_holds_1khz() -> None:
    stats = RateLoop(1000.0, clock=MonotonicClock()).run(lambda t: None, duration_s=0.5)
    assert abs(stats.ticks + stats.skipped - 500) <= 1  # every deadline ticked or skipped
    assert stats.lateness_percentile_s(50) < 200e-6  # (this machine is shared: no tail bound)


def test_a_service_keeps_per_tick_timing_only_for_stats_json() -> None:
    """``teleop up`` grew 6 MB a minute per 1 kHz service while the loop kept every tick's
    timing for nobody: now the timing goes nowhere unless ``--stats-json`` reads it."""
    from services.process import ServiceOptions, _timing_sink

    sink = _timing_sink(None, ServiceOptions("master"))
    assert sink is not None  # a callback: the loop keeps nothing
    stats = RateLoop(1000.0, clock=VirtualClock()).run(lambda t: None, duration_s=0.5,
                                                       timing=sink)
    assert stats.ticks == 500 and stats.lateness_s.size == 0 and stats.tick_s.size == 0
    assert _timing_sink(None, ServiceOptions("master", stats_path="s.json")) is None
