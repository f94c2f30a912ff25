"""`teleop bench servo`: figures with units, from real pty round trips."""

from __future__ import annotations

import pytest

from sim.servo_emulator_bench import bench_servo, wire_bytes_per_cycle


def test_wire_bytes_follow_the_packet_formats() -> None:
    # P1: SYNC_WRITE 8 + 4 x (id + 4 data) = 28; 4 x (READ 8 + status 6 + 8 data) = 88
    assert wire_bytes_per_cycle(1) == 116
    # BULK_READ 7 + 3 x 4 = 19; 4 statuses of 14
    assert wire_bytes_per_cycle(1, bulk=True) == 28 + 19 + 56


@pytest.mark.slow
def test_bench_servo_reports_cycle_times() -> None:
    fig = bench_servo(cycles=60)
    for pre in ("p1_", "p1_bulk_", "p2_"):
        assert 0 < fig[pre + "p50_us"] <= fig[pre + "p99_us"] <= fig[pre + "max_us"]
        assert (fig[pre + "stalls"] > 0) == (fig[pre + "max_us"] > 20_000.0)
        assert fig[pre + "cycles_per_s"] > 10  # a pty round trip is far below 100 ms
    assert fig["p50_us"] == fig["p1_p50_us"]
    assert fig["max_us"] == fig["p1_max_us"] and fig["stalls"] == fig["p1_stalls"]
    assert fig["p1_wire_time_at_57142_baud_us"] == pytest.approx(116 * 10 / 57142 * 1e6)
