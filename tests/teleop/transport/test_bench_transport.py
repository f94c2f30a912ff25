"""``teleop bench transport``: the CLI path and the sanity of its figures (short run)."""

from __future__ import annotations

import functools
import json
from pathlib import Path

import pytest

from teleop.cli import main
from teleop.transport import bench


@pytest.mark.network
def test_bench_transport_json(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(bench, "bench_transport",
                        functools.partial(bench.bench_transport, duration_s=0.3))
    out = tmp_path / "bench.json"
    assert main(["bench", "transport", "--json", str(out)]) == 0
    fig = json.loads(out.read_text())
    for key in ("p50_us", "p99_us", "delay_error_p99_us", "messages_per_s", "raw_rtt_p50_us",
                "raw_rtt_p99_us", "rtt_p50_us"):
        assert isinstance(fig[key], float) and fig[key] > 0, key
    # one-way latency is positive and below a round trip; loopback is well under 50 ms
    assert 0 < fig["p50_us"] < fig["rtt_p50_us"] < 50_000
    assert fig["raw_rtt_p50_us"] < 50_000
    # the 50 ms delay line never releases early and is typically accurate to < 1 ms
    assert fig["delay_error_min_us"] >= -1.0
    assert fig["delay_error_p50_us"] < 1000.0
    assert fig["received_fraction"] >= 0.95 and fig["delay_received_fraction"] >= 0.95
    assert fig["messages_per_s"] > 1000.0
    # every p99 has its max beside it, and max >= p99 >= p50 (a stall cannot hide)
    for prefix in ("", "backward_", "rtt_", "raw_rtt_"):
        p50, p99, top = (fig[f"{prefix}{q}_us"] for q in ("p50", "p99", "max"))
        assert top >= p99 >= p50 > 0, prefix
        assert (fig[f"{prefix}stalls"] > 0) == (top > bench.STALL_US), prefix
    assert fig["written_off"] >= 0
    assert fig["delay_error_max_us"] >= fig["delay_error_p99_us"] >= 0
    assert fig["delay_error_max_us"] >= abs(fig["delay_error_min_us"])


def test_unknown_bench_is_a_one_line_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "nope"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown benchmark 'nope'" in err[0]
