"""The master's tank operations and the hand's set-position modulation."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from teleop.control.energy_tank import (
    cap_tank,
    franken_limit,
    guard_force,
    port_work_j,
    quantum_j,
    tlc_damping,
)
from teleop.control.passivity_layer import dissipation_lower_bound_j, pspm_project

finite = st.floats(-10.0, 10.0)


@settings(max_examples=300, deadline=None)
@given(f=finite, v=st.floats(-2.0, 2.0), h=st.floats(-1.0, 1.0))
def test_franken_limiter_keeps_sign_and_budget(f: float, v: float, h: float) -> None:
    dt = 1e-3
    g = franken_limit(f, v, h, dt)
    assert abs(g) <= abs(f) and (g == 0.0 or math.copysign(1, g) == math.copysign(1, f))
    assert -g * v * dt <= max(h, 0.0) + 1e-12  # predicted delivery within the budget


@settings(max_examples=300, deadline=None)
@given(f=finite, v=st.floats(-2.0, 2.0), h=st.floats(-1.0, 1.0), dq=st.floats(-1e-3, 1e-3))
def test_guard_makes_any_bounded_motion_affordable(f: float, v: float, h: float,
                                                   dq: float) -> None:
    """Whatever the trigger does within the speed bound, the tank cannot go below zero."""
    g = guard_force(f, h, v, 1.0, 1e-3)
    assert abs(g) <= abs(f)
    if h >= 0:
        assert h - port_work_j(g, dq) >= -1e-15
    else:
        assert g == 0.0  # an empty (negative) tank never flips or keeps a force


def test_tlc_damping_is_capped_for_the_sampled_damper() -> None:
    # deficit large: capped by d_max and by m / (2 T)
    assert tlc_damping(0.0, 1.0, 1e6, 100.0, 0.05, 1e-3) == 25.0
    assert tlc_damping(0.0, 1.0, 1e6, 10.0, 0.05, 1e-3) == 10.0
    assert tlc_damping(2.0, 1.0, 20.0, 10.0, 0.05, 1e-3) == 0.0  # full tank: no damping
    assert math.isclose(tlc_damping(0.9, 1.0, 20.0, 10.0, 0.05, 1e-3), 2.0)


def test_cap_and_quantum() -> None:
    assert cap_tank(6.0, 5.0) == (5.0, 1.0)
    assert cap_tank(4.0, 5.0) == (4.0, 0.0)
    assert quantum_j(1.0, 0.25, 0.1) == 0.1 * 0.75
    assert quantum_j(-1.0, 0.25, 0.1) == 0.0  # never negative energy on the wire


@settings(max_examples=300, deadline=None)
@given(des=st.tuples(finite, finite, finite), prev=st.tuples(finite, finite, finite),
       x=st.tuples(finite, finite, finite), budget=st.floats(-1.0, 5.0))
def test_pspm_never_spends_more_than_the_budget(des: tuple[float, float, float],
                                                prev: tuple[float, float, float],
                                                x: tuple[float, float, float],
                                                budget: float) -> None:
    y, dp, limited = pspm_project(des, prev, x, budget, 13.0)
    assert dp <= max(budget, 0.0) + 1e-12
    if not limited:
        assert y == des
    assert all(math.isfinite(v) for v in y)


def test_dissipation_bound_is_cauchy_schwarz() -> None:
    # a constant-velocity move of 0.1 rad in 0.1 s through damping 2 dissipates 2 * 1^2 * 0.1
    assert math.isclose(dissipation_lower_bound_j((0.1, 0, 0), (0, 0, 0), 2.0, 0.1), 0.2)
