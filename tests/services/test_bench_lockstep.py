"""``teleop bench lockstep``: both engines side by side, ratios and the profile split."""

from __future__ import annotations

import pytest

from services.bench_lockstep import bench_lockstep


def test_bench_lockstep_reports_both_engines_and_where_the_time_goes() -> None:
    fig = bench_lockstep(sim_time_s=0.5, repeats=1)
    for what in ("lockstep", "simhand"):
        py, co = fig[f"python_{what}_realtime_factor"], fig[f"compiled_{what}_realtime_factor"]
        assert py > 0.0 and co > 0.0
        assert fig[f"compiled_{what}_over_python"] == pytest.approx(co / py)
    shares = {k: v for k, v in fig.items() if k.startswith("profile_share_")}
    assert sum(shares.values()) == pytest.approx(1.0)
    assert shares["profile_share_transport"] > 0.0 and shares["profile_share_control"] > 0.0
    assert all(isinstance(v, float) for v in fig.values())
