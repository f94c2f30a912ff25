"""Per-grasp analysis on synthetic grasp series."""

from __future__ import annotations

import math

import numpy as np
import pytest

from teleop.analysis.grasps import analyse_grasps, format_grasps, grasp_windows, held_max

T = np.arange(0.0, 30.0, 1e-2)


def trigger(t: np.ndarray, period: float = 4.5, until: float = 1e9) -> np.ndarray:
    phase = np.fmod(t, period)
    closed = (phase > 0.5) & (phase < 3.5) & (t < until)
    return np.where(closed, 0.009, 0.0)  # held short of full travel by the force


def test_windows_start_at_each_closing_and_drop_an_unfinished_grasp() -> None:
    x = trigger(T)  # closes at 0.5, 5.0, ... 27.5 (still closed at the end: dropped)
    w = grasp_windows(T, x, 0.0025)
    assert len(w) == 6
    assert [round(a, 2) for a, _ in w] == pytest.approx([0.51, 5.01, 9.51, 14.01, 18.51, 23.01])
    assert w[0][1] == pytest.approx(w[1][0])


def test_hysteresis_ignores_chatter_around_the_threshold() -> None:
    x = trigger(T) + 0.0004 * np.sin(2 * np.pi * 20 * T)  # +-0.4 mm chatter
    x = np.where(x > 0.001, x, 0.0024 + 0.0004 * np.sin(2 * np.pi * 20 * T))  # near 2.5 mm
    assert len(grasp_windows(T, x, 0.0025)) == 0  # never opens below half: no grasp ends
    assert len(grasp_windows(T, trigger(T), 0.0025)) == 6


def test_weakening_grasps_are_measured_against_the_first() -> None:
    x = trigger(T)
    k = np.floor(T / 4.5)
    peak = np.where(k >= 3, 60.0, 600.0)
    p = np.zeros((len(T), 27))
    p[:, 13] = np.where(x > 0, peak, 2.0)
    q = np.column_stack([x * 30, x * 20, x * 10])
    f = np.where(x > 0, np.where(k >= 3, 0.5, 8.0), 0.0)
    g = analyse_grasps(T, x, p, q, f, 0.0025)
    assert len(g.grasps) == 6
    assert [gr.pressure_ratio for gr in g.grasps] == pytest.approx([1, 1, 1, 0.1, 0.1, 0.1])
    assert g.min_pressure_ratio == pytest.approx(0.1)
    assert g.min_felt_ratio == pytest.approx(0.0625)
    assert g.grasps[0].closure_rad == pytest.approx(0.27)
    assert g.min_closure_ratio == pytest.approx(1.0)
    text = format_grasps(g, every=10)
    assert "0.10" in text and len(text.splitlines()) == 4  # head, first, weakest, last


def test_no_grasp_gives_nan() -> None:
    g = analyse_grasps(T, np.zeros_like(T), np.zeros((len(T), 27)), np.zeros((len(T), 3)),
                       np.zeros_like(T), 0.0025)
    assert g.grasps == () and math.isnan(g.min_pressure_ratio)


def test_closure_is_the_angle_held_not_an_impact_overshoot() -> None:
    """The first grasp's link overshoots for one 25 ms hand sample at the impact (0.12 rad,
    then 0.08 held); the second holds 0.103 for 0.3 s and spikes to 0.2 for 40 ms.  Held
    closures 0.08 and 0.103; the plain largest angles (kept beside) 0.12 and 0.2."""
    t = np.arange(0.0, 9.0, 1e-3)
    x = trigger(t)
    q = np.where(x > 0, 0.08, 0.0)
    q[(t >= 1.0) & (t < 1.025)] = 0.12  # grasp 0: impact overshoot, one hand sample
    q[(t >= 5.5) & (t < 5.8)] = 0.103  # grasp 1: the touch held 0.3 s
    q[(t >= 6.0) & (t < 6.04)] = 0.2  # a 40 ms spike later in it: not held either
    p = np.zeros((len(t), 27))
    p[:, 4] = np.where(x > 0, 100.0, 0.0)
    g = analyse_grasps(t, x, p, q[:, None], x, 0.0025)
    assert len(g.grasps) == 2
    g0, g1 = g.grasps[0], g.grasps[1]
    assert g0.closure_rad == pytest.approx(0.08) and g0.peak_closure_rad == pytest.approx(0.12)
    assert g1.closure_rad == pytest.approx(0.103) and g1.peak_closure_rad == pytest.approx(0.2)
    assert g1.closure_ratio == pytest.approx(0.103 / 0.08)
    plain = analyse_grasps(t, x, p, q[:, None], x, 0.0025, hold_s=0.0)
    assert plain.grasps[1].closure_ratio == pytest.approx(0.2 / 0.12)


def test_held_max_keeps_a_hold_of_exactly_the_window_and_drops_a_shorter_one() -> None:
    t = np.arange(0.0, 2.0, 1e-3)
    q = np.zeros((len(t), 2))
    q[(t >= 0.5) & (t < 0.61), 0] = 1.0  # 110 ms: held
    q[(t >= 1.0) & (t < 1.08), 1] = 2.0  # 80 ms: not
    assert held_max(t, q, 0.1) == pytest.approx(1.0)
    assert math.isnan(held_max(t[:50], q[:50], 0.1))  # shorter than the window
    hand = np.arange(0.0, 2.0, 0.025)  # hand-rate samples, irregular by a jitter
    hand = hand + np.random.default_rng(0).uniform(0, 0.004, len(hand))
    qh = np.where((hand >= 0.5) & (hand < 0.65), 1.0, 0.0)[:, None]
    assert held_max(hand, qh, 0.1) == pytest.approx(1.0)
    assert held_max(hand, qh, 0.2) == pytest.approx(0.0)


def test_without_pressures_the_weakest_grasp_is_the_least_closed() -> None:
    # a hand without tactile cells (the dynamixel layout) reads zero pressures: no pressure
    # ratio, so the weakest grasp is found by closure, and the missing ratios print as '-'
    x = trigger(T)
    k = np.floor(T / 4.5)
    q = np.column_stack([x * np.where(k == 4, 10, 30), x * 20, x * 10])
    g = analyse_grasps(T, x, np.zeros((len(T), 27)), q, np.where(x > 0, 1.0, 0.0), 0.0025)
    assert g.weakest is g.grasps[4] and g.min_closure_ratio == pytest.approx(2 / 3)
    rows = format_grasps(g, every=10).splitlines()
    assert [r.split()[0] for r in rows[1:]] == ["0", "4", "5"]  # first, weakest, last
    assert rows[1].split()[3] == "-"


def test_felt_not_held_needs_a_full_feel_and_a_weak_grip() -> None:
    from teleop.analysis.grasps import GraspSeries, GraspStats

    def g(i: int, p: float, f: float) -> GraspStats:
        return GraspStats(index=i, t_start_s=4.5 * i, t_end_s=4.5 * i + 4.5,
                          peak_pressure=600.0 * p, closure_rad=0.9, felt_force_n=8.0 * f,
                          pressure_ratio=p, closure_ratio=1.0, felt_ratio=f)

    s = GraspSeries((g(0, 1.0, 1.0), g(1, 0.3, 1.0), g(2, 0.3, 0.3), g(3, 0.5, 0.95),
                     g(4, 0.1, 0.9), g(5, math.nan, 1.0)))
    # 1: felt in full at 0.3 of the pressure; 4: felt at the threshold at 0.1. Not 2 (felt as
    # weak as it was held), 3 (half the pressure is weak, not absent), 5 (no pressure ratio)
    assert [x.index for x in s.felt_not_held] == [1, 4]


def test_felt_not_held_only_where_the_pressure_asked_for_less_than_was_felt() -> None:
    """With the measured-force command recorded: a third of the pressure that still asked
    for the full display (the trigger's force saturates) was felt as held; one that asked
    for under half of what was felt was not."""
    from teleop.analysis.grasps import GraspSeries, GraspStats

    def g(i: int, p: float, measured_n: float) -> GraspStats:
        return GraspStats(index=i, t_start_s=4.5 * i, t_end_s=4.5 * i + 4.5,
                          peak_pressure=4000.0 * p, closure_rad=0.9, felt_force_n=8.0,
                          pressure_ratio=p, closure_ratio=1.0, felt_ratio=1.0,
                          measured_force_n=measured_n)

    s = GraspSeries((g(0, 1.0, 8.0), g(1, 0.3, 8.0), g(2, 0.3, 2.0), g(3, 0.3, 4.0),
                     g(4, 0.3, 3.99), g(5, 0.6, 1.0)))
    # 1 asked for 8 N; 3 for half of the 8 N felt (the boundary); 5 held 0.6 of the pressure
    assert [x.index for x in s.felt_not_held] == [2, 4]


def _series_of(peaks: list[float], closures: list[float] | None = None):  # noqa: ANN202
    from teleop.analysis.grasps import GraspSeries, GraspStats

    closures = closures or [0.9] * len(peaks)
    return GraspSeries(tuple(
        GraspStats(index=i, t_start_s=4.5 * i, t_end_s=4.5 * i + 4.5, peak_pressure=p,
                   closure_rad=c, felt_force_n=8.0,
                   pressure_ratio=p / peaks[0] if peaks[0] > 0 else math.nan,
                   closure_ratio=c / closures[0], felt_ratio=1.0)
        for i, (p, c) in enumerate(zip(peaks, closures, strict=True))))


def test_a_first_grasp_out_of_line_is_told_apart_from_a_loss() -> None:
    """The soft operator on the block at 100 ms in lockstep: the first grasp overshoots
    (226), the rest hold at 180-199. Over the first alone that reads 0.80."""
    s = _series_of([226, 180, 186, 186, 191, 193, 196, 190, 199])
    a = s.after_first()
    assert s.min_pressure_ratio == pytest.approx(180 / 226)
    assert a is not None and a.measure == "peak_pressure" and a.early == 3
    assert a.early_best_over_first == pytest.approx(186 / 226)
    assert a.later_weakest_over_early_best == pytest.approx(190 / 186)
    assert a.later_weakest_index == 7
    assert "the best of the next 3 0.82 of the first" in a.describe()


def test_a_collapse_after_the_first_grasp_is_not_hidden() -> None:
    """The original defect (tanks empty from the second grasp on): the early best itself
    is a sliver of the first, and the later grasps fall further still."""
    a = _series_of([675, 5, 4, 3, 3, 2]).after_first()
    assert a is not None
    assert a.early_best_over_first == pytest.approx(5 / 675)
    assert a.later_weakest_over_early_best == pytest.approx(2 / 5)


def test_without_pressures_the_closure_is_compared_and_short_runs_give_nothing() -> None:
    s = _series_of([0.0] * 6, [1.2, 0.7, 0.68, 0.7, 0.69, 0.66])  # no cells: ratios nan
    a = s.after_first()
    assert a is not None and a.measure == "closure_rad"
    assert a.early_best_over_first == pytest.approx(0.7 / 1.2)
    assert a.later_weakest_over_early_best == pytest.approx(0.66 / 0.7)
    assert _series_of([600, 600, 600, 600]).after_first() is None  # needs early + 2 grasps
