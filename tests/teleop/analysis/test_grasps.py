"""Per-grasp analysis on synthetic grasp series."""

from __future__ import annotations

import math

import numpy as np
import pytest

from teleop.analysis.grasps import analyse_grasps, format_grasps, grasp_windows

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
