"""The typed term library, its sparse regression, and the input's sample alignment."""

from __future__ import annotations

import math

import numpy as np
import pytest

from teleop.diagnose.axis_model import AxisParams, simulate_axis
from teleop.diagnose.library import Term, equation, units
from teleop.diagnose.propose import stlsq
from teleop.effects import EffectSet


def test_a_term_key_parses_back_to_the_same_term() -> None:
    for term in (Term("sin", 25.125), Term("vabsv"), Term("udelay", 0.02)):
        assert Term.parse(term.key) == term
    with pytest.raises(ValueError):
        Term.parse("term:bogus:1")


def test_a_cubic_library_term_simulates_like_the_catalog_cubic_spring() -> None:
    # two code paths of the simulator for the same physics: effort -k3 x^3
    t = np.arange(0, 2, 0.001)
    u = 20 * np.sin(2 * math.pi * 1.3 * t)
    p = AxisParams(1.0, 0.8, 40.0)
    catalog = simulate_axis(t, u, p, EffectSet(nonlinear_stiffness=30.0))
    lib = simulate_axis(t, u, AxisParams(1.0, 0.8, 40.0, terms=((Term("x3").key, -30.0),)))
    assert np.max(np.abs(catalog - lib)) < 1e-9
    assert np.max(np.abs(catalog - simulate_axis(t, u, p))) > 1e-2  # the term does act


def test_input_shift_is_the_input_moved_in_time() -> None:
    t = np.arange(0, 2, 0.001)
    u = 10 * np.sin(2 * math.pi * 2.0 * t)
    p = AxisParams(1.0, 1.0, 50.0, input_shift_s=-0.0005)
    moved = np.interp(t + 0.0005, t, u, right=u[-1])
    assert np.max(np.abs(simulate_axis(t, u, p) - simulate_axis(t, moved, AxisParams(
        1.0, 1.0, 50.0)))) < 1e-12


def test_stlsq_keeps_the_terms_that_made_the_data_and_drops_the_rest() -> None:
    rng = np.random.default_rng(4)
    a = rng.standard_normal((2000, 6))
    truth = np.array([0.0, 2.0, 0.0, 0.0, -0.7, 0.0])
    b = a @ truth + 0.05 * rng.standard_normal(2000)
    coef = stlsq(a, b, owner=[0, 1, 2, 3, 4, 5])
    assert np.flatnonzero(coef).tolist() == [1, 4]
    assert np.allclose(coef[[1, 4]], [2.0, -0.7], atol=0.01)


def test_stlsq_keeps_or_drops_a_sin_cos_pair_together() -> None:
    rng = np.random.default_rng(5)
    x = rng.uniform(-1, 1, 3000)
    a = np.column_stack([np.sin(20 * x), np.cos(20 * x), x ** 3])
    b = 1.5 * np.sin(20 * x) + 0.01 * rng.standard_normal(3000)
    coef = stlsq(a, b, owner=[0, 0, 1])
    assert coef[2] == 0.0 and coef[0] != 0.0 and coef[1] != 0.0


def test_the_equation_carries_units_from_the_column_names() -> None:
    eq = equation({Term("sin", 25.0).key: -0.5, Term("vabsv").key: 0.01},
                  units("torque_nm", "?"), units("angle_rad", "?"))
    assert "effort [N m] +=" in eq
    assert "0.5 [N m] * sin(25 rad^-1 * x)" in eq
    assert "[N m s^2/rad^2] * v*|v|" in eq
    assert units("whatever", "effort units") == "effort units"


def test_with_a_delay_the_input_before_the_record_is_a_parameter_not_the_first_sample() -> None:
    t = np.arange(0, 1, 0.001)
    u = 10 + 5 * np.sin(2 * math.pi * 2.0 * t)      # starts far from zero
    p = AxisParams(1.0, 1.0, 50.0)
    switched_on = np.interp(t - 0.05, t, u, left=0.0)  # nothing acted before t = 0
    held = np.interp(t - 0.05, t, u, left=u[0])
    eff = EffectSet(dead_time=0.05)
    assert np.max(np.abs(simulate_axis(t, u, p, eff, u_before=0.0)
                         - simulate_axis(t, switched_on, p))) < 1e-12
    assert np.max(np.abs(simulate_axis(t, u, p, eff) - simulate_axis(t, held, p))) < 1e-12
