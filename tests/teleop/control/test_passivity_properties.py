"""Property tests: random delay, jitter (reordering), loss, duplication, operator motion and
environment; the passive controllers must never generate energy.

Checked at every 1 ms sample of the closed loop (``_ctl_harness``):
* physical truth (the harness's own energy audit, no controller code): energy delivered at
  the operator port (work of the displayed force on the operator) and at the environment
  port (work of the fingers on the spring wall) <= the initial energy of all tanks + the
  energy taken from both ports;
* the controllers' own ledgers pass :func:`energy_balance` (delivered <= initial + taken,
  links create nothing, books balance, tanks >= 0, nothing NaN) - a second, separate check.
"""

from __future__ import annotations

import math
from dataclasses import replace

import pytest
from _ctl_harness import Scenario, audit_failure, initial_tank_j, run_loop
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from teleop.config.control import ControllerConfig
from teleop.control.energy_channel import energy_balance
from teleop.control.interface import control_params
from teleop.control.registry import CONTROLLERS

scenarios = st.builds(
    Scenario,
    seed=st.integers(0, 10_000),
    steps=st.just(1200),
    delay_steps=st.sampled_from([0, 1, 5, 20, 100, 300]),
    jitter_steps=st.sampled_from([0, 3, 30]),
    loss=st.sampled_from([0.0, 0.1, 0.5, 0.9]),
    dup=st.sampled_from([0.0, 0.2]),
    hand_every=st.sampled_from([1, 5, 25]),
    op_mass_kg=st.floats(0.02, 0.2),
    op_stiffness=st.floats(50.0, 2000.0),
    op_damping=st.floats(0.5, 15.0),
    op_force_n=st.floats(0.0, 10.0),
    ref_fraction=st.floats(0.2, 1.0),
    ref_period_s=st.floats(0.1, 1.5),
    random_ref=st.booleans(),
    wall_rad=st.tuples(*(st.floats(0.2, 3.0),) * 3),
    contact_stiffness=st.floats(0.5, 50.0),
    pressure_per_nm=st.floats(10.0, 2000.0),
    servo_damping_factor=st.floats(1.0, 3.0),
)


def check_run(kind: str, sc: Scenario, **overrides: float) -> None:
    """Run the loop and check the invariants at every sample (in hand-side joules when the
    controller scales power by ``energy_scale`` = rho: master energies count rho times)."""
    p = replace(control_params(ControllerConfig(kind=kind)), **overrides)
    rho = p.energy_scale
    suite = CONTROLLERS[kind]
    tr = run_loop(suite, p, sc)
    fail = audit_failure(tr, initial_tank_j(suite, p), rho)
    assert not fail, fail
    for k, leds in enumerate(tr.ledgers):
        rep = energy_balance(leds, weights=(rho, 1.0, 1.0))
        assert rep.ok, (k, rep.reason)
        assert all(led.tank_j >= -1e-12 for led in leds), k
    assert all(math.isfinite(f) for f in tr.force_n)


@pytest.mark.parametrize("kind", ["two-layer", "tdpa"])
@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(sc=scenarios)
def test_passive_controllers_never_generate_energy(kind: str, sc: Scenario) -> None:
    check_run(kind, sc)


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(sc=scenarios, split=st.floats(0.0, 1.0), beta=st.floats(0.0, 1.0),
       reserve=st.floats(0.0, 2.0), initial=st.floats(0.0, 3.0))
def test_two_layer_passive_for_any_tank_tuning(sc: Scenario, split: float, beta: float,
                                               reserve: float, initial: float) -> None:
    check_run("two-layer", sc, controller_split=split, transfer_fraction=beta,
              controller_fraction=beta, reserve_j=reserve, initial_j=initial)


@pytest.mark.parametrize("kind", ["two-layer", "tdpa"])
@settings(max_examples=5, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(sc=scenarios, rho=st.floats(1.0, 100.0))
def test_power_scaled_controllers_are_passive_in_scaled_energy(kind: str, sc: Scenario,
                                                               rho: float) -> None:
    check_run(kind, sc, energy_scale=rho)


def test_direct_control_fails_the_same_check() -> None:
    """The check can fail: direct control with delay into a stiff contact generates energy."""
    sc = Scenario(steps=3000, delay_steps=50, hand_every=25, wall_rad=(1.5, 1.5, 1.5))
    suite, p = CONTROLLERS["direct"], control_params(ControllerConfig(kind="direct"))
    assert audit_failure(run_loop(suite, p, sc), initial_tank_j(suite, p))
    with pytest.raises(AssertionError):
        check_run("direct", sc)
