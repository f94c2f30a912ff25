"""The soak's figures from synthetic logs: each check is made to fail once on purpose."""

from __future__ import annotations

import numpy as np
import pytest

from services.soak_log import TIMING_DTYPE
from services.soak_report import (
    energy_audit,
    grasps,
    growth,
    latency_windows,
    recovery_s,
    watchdog_share,
)


def _timing(t: np.ndarray, late: np.ndarray, stall: np.ndarray | None = None) -> np.ndarray:
    a = np.zeros(t.size, dtype=TIMING_DTYPE)
    a["t_s"], a["late_s"] = t, late
    a["stall_s"] = 0.0 if stall is None else stall
    return a


def test_latency_window_max_includes_the_stall_the_p99_does_not() -> None:
    t = np.arange(0.0, 20.0, 0.001)
    late = np.full(t.size, 50e-6)
    stall = np.zeros(t.size)
    stall[15_000] = 0.4  # one 400 ms stall in the second window, re-based lateness small
    w = latency_windows({"master": [_timing(t, late, stall)]}, 10.0, 0.0, 20.0)
    assert [x["master"]["stalls"] for x in w] == [0, 1]
    assert w[1]["master"]["p99_us"] == pytest.approx(50.0, rel=1e-3)
    assert w[1]["master"]["max_us"] == pytest.approx(400_000.0, rel=1e-3)
    assert w[0]["master"]["max_us"] == pytest.approx(50.0, rel=1e-3)
    tail = latency_windows({"master": [_timing(t, late, stall)]}, 9.0, 0.0, 20.0)
    assert [(x["start_s"], x["end_s"]) for x in tail] == [(0.0, 9.0), (9.0, 20.0)]


def test_latency_windows_leave_out_the_start_up() -> None:
    t = np.arange(0.0, 10.0, 0.01)
    late = np.where(t < 3.0, 0.2, 1e-4)  # slow start-up, then fine
    w = latency_windows({"hand": [_timing(t, late)]}, 7.0, 3.0, 10.0)
    assert len(w) == 1 and w[0]["hand"]["max_us"] < 200.0


def test_growth_is_measured_after_the_warm_up_on_medians() -> None:
    samples = [(t, "hand", 1, 50.0 + (40.0 if t >= 10 else 0.0) + 0.1 * t, 10)
               for t in range(0, 100, 5)]
    g = growth(samples, warmup_s=20.0)[0]
    assert g["rss_warm_mb"] == pytest.approx(93.0)  # median of t = 20 ... 40 s
    assert g["rss_end_mb"] == pytest.approx(98.5)  # median of the last five
    assert g["rss_growth_pct"] == pytest.approx(100 * 5.5 / 93.0)
    leak = [(t, "hand", 1, 50.0 + t, 10) for t in range(0, 100, 5)]
    assert growth(leak, 20.0)[0]["rss_growth_pct"] > 10.0
    spike = [(t, "m", 1, 60.0 + (12.0 if t in (50, 55) else 0.0), 10) for t in range(0, 100, 5)]
    assert growth(spike, 20.0)[0]["rss_growth_pct"] == 0.0  # up and down again: no growth
    short = growth([(float(t), "c", 2, 50.0 + t, 9) for t in range(0, 60, 5)], 20.0)[0]
    assert short["rss_growth_pct"] is None  # fewer than 2 x 5 samples after warm-up
    # a 20 MB step inside an excluded window (a flood) counts only in the plain growth
    step = [(t, "hand", 1, 100.0 + (20.0 if t >= 50 else 0.0) + 0.01 * t, 10)
            for t in range(0, 100, 5)]
    g = growth(step, 20.0, [(48.0, 52.0)])[0]
    assert g["rss_growth_pct"] == pytest.approx(100 * 20.55 / 100.3)
    assert g["rss_in_floods_mb"] == pytest.approx(20.1)  # two 5 s intervals touch the window
    assert g["rss_growth_outside_pct"] == pytest.approx(100 * 0.45 / 100.3)


def _status(t: np.ndarray, wd: np.ndarray) -> list[dict[str, float]]:
    return [{"t_s": float(a), "wd": int(b)} for a, b in zip(t, wd, strict=True)]


def test_thread_growth_counts_threads_that_stay_not_transient_ones() -> None:
    """A zenoh session starts a worker now and then (10 -> 11 for a few samples); a leaked
    thread stays.  One transient thread in the last samples is not growth; the mutant rule
    (medians) read the soak's master, 10 threads, as 10 % growth."""
    transient = [(float(t), "m", 3, 50.0, 11 if t in (100, 110, 115) else 10)
                 for t in range(0, 120, 5)]
    assert growth(transient, 20.0)[0]["threads_growth_pct"] == 0.0
    leak = [(float(t), "m", 3, 50.0, 10 + (t >= 60)) for t in range(0, 120, 5)]
    assert growth(leak, 20.0)[0]["threads_growth_pct"] == pytest.approx(10.0)


def test_recovery_waits_for_every_watchdog_and_a_silent_role_is_not_clear() -> None:
    t = np.arange(0.0, 30.0, 0.1)
    hand = _status(t, (t >= 10) & (t < 12.3))
    ctrl = _status(t, (t >= 10) & (t < 11.0))
    assert recovery_s([hand, ctrl], 11.0, 20.0) == pytest.approx(1.3, abs=0.06)
    never = _status(t, t >= 10)
    assert recovery_s([never, ctrl], 11.0, 10.0) is None
    silent = _status(t[t < 11.0], np.zeros(int(np.sum(t < 11.0))))
    assert recovery_s([silent, ctrl], 11.0, 10.0) is None
    share = watchdog_share({"hand": hand, "c": ctrl}, 10.0, 15.0)
    assert share["hand"] == pytest.approx(46.0) and share["c"] == pytest.approx(20.0)


def _audited(t: np.ndarray, delivered: np.ndarray, taken: np.ndarray, initial: float
             ) -> list[dict[str, float]]:
    return [{"t_s": float(a), "audit_delivered_j": float(d), "audit_taken_j": float(k),
             "initial_j": initial} for a, d, k in zip(t, delivered, taken, strict=True)]


def test_energy_audit_counts_a_restarted_controllers_energy_and_catches_a_deficit() -> None:
    t = np.arange(0.0, 10.0, 0.1)
    m = _audited(t, 0.5 * t, 0.4 * t, 1.0)  # the operator receives 0.1 J/s net
    h = _audited(t, np.zeros_like(t), np.zeros_like(t), 1.0)
    a = energy_audit(m, h, [], 1.0)
    assert a["violations"] == 0 and a["min_margin_j"] == pytest.approx(2.0 - 0.99, abs=1e-6)
    deficit = _audited(t, 0.8 * t, 0.4 * t, 1.0)  # 0.4 J/s net out: negative after 5 s
    bad = energy_audit(deficit, h, [], 1.0)
    assert bad["violations"] > 0 and bad["min_margin_j"] < 0
    ctrl = [{"t_s": 4.0, "initial_j": 10.0}]  # a controller that started at 4 s with 10 J
    assert energy_audit(deficit, h, [ctrl], 1.0)["violations"] == int(np.sum(
        (2.0 - 0.4 * t < 0) & (t < 4.0)))
    assert not energy_audit([{"t_s": 0.0, "initial_j": 1.0}], h, [], 1.0)["audited"]


def test_grasps_count_closures_and_contact_episodes() -> None:
    trig = [{"trigger_m": x} for x in (0, 0.02, 0.02, 0, 0.001, 0.02, 0)]
    hand = [{"contacts": c} for c in (0, 3, 0, 0, 2, 2, 0)]
    assert grasps(trig, hand, 0.025) == {"closures": 2, "contact_episodes": 2}
