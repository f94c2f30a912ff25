"""The compiled physics engine against the Python reference step (issue 16).

Every ``teleop sim`` experiment runs 10 s on both engines (with and without effects, the
delay line included), and the whole hand grasps a cylinder and a block for 10 s with its
energy audit: the compiled engine must stay within 1e-9 rad of the reference everywhere.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from sim.compiled import compiled_finger_step, compiled_hung_weight_step
from sim.contact import ContactObject
from sim.engine import ENGINES, engine
from sim.experiments import EXPERIMENTS, ExperimentSpec, run_experiment
from sim.finger import (
    MotorCommand,
    default_finger_params,
    finger_step,
    hung_weight_step,
    initial_finger_state,
)
from sim.hand import HandMotorCommand, default_hand_params, initial_hand_state
from sim.params import JOINT_RATIO
from teleop.effects import EffectSet
from teleop.errors import UserInputError

TOL_RAD = 1e-9
ANGLES = ("motor_angle_rad", "joint_angle_rad", "proximal_angle_rad", "distal_angle_rad")
EFFECTS = EffectSet(dead_time=0.03, coulomb_friction=0.5, asymmetric_friction=0.3,
                    stiction=0.8, backlash=0.02, actuator_saturation=60.0, actuator_gain=1.1,
                    actuator_lag=0.01, sensor_offset=0.01, series_compliance=200.0,
                    nonlinear_stiffness=0.002, gravity=0.5)


def _both(name: str, effects: EffectSet, obj: ContactObject) -> tuple[object, object]:
    spec = ExperimentSpec(name, duration_s=10.0)
    p = default_finger_params()
    return tuple(run_experiment(spec, p, obj, effects, engine_name=e) for e in ENGINES)


@pytest.mark.parametrize("effects", [EffectSet(), EFFECTS], ids=["nominal", "all-effects"])
@pytest.mark.parametrize("name", EXPERIMENTS)
def test_every_experiment_matches_the_reference_for_10_s(name: str,
                                                         effects: EffectSet) -> None:
    compiled, python = _both(name, effects, ContactObject(kind="cylinder"))
    a, b = compiled.recording, python.recording
    assert a.t_s[-1] == pytest.approx(10.0) and len(a.t_s) == len(b.t_s)
    moved = 0.0
    for col in ANGLES:
        ref = b.column(col)
        assert np.max(np.abs(a.column(col) - ref)) <= TOL_RAD, col
        moved = max(moved, float(np.ptp(ref)))
    assert moved > 0.05  # the run exercised the dynamics (a still finger proves nothing)
    assert np.max(np.abs(a.data - b.data)) <= 1e-6  # loads, forces, pressures too
    assert compiled.summary == pytest.approx(python.summary)


def _hand_grasp(name: str, obj: ContactObject, steps: int,
                release: bool = False) -> tuple[object, list[list[float]]]:
    """Close the hand into ``obj`` (with ``release``: open it again halfway)."""
    hp = default_hand_params()
    st = initial_hand_state(hp)
    audit: tuple[list[float], list[float]] = ([0.0] * 3, [0.0] * 3)
    run = engine(name).run_hand
    n = steps // 25
    for k in range(n):  # 40 Hz commands, as the hand service's reads
        sp = min(1.6, 0.05 * k) if not release or k < n // 2 else 0.0
        ms = tuple(MotorCommand("position", JOINT_RATIO * sp * f) for f in (1.0, 0.9, 0.8))
        st = run(st, HandMotorCommand((ms[0], ms[1], ms[2]), 0.3), hp, obj, EffectSet(), 1e-3,
                 25, audit=audit)
    return st, [audit[0], audit[1]]


@pytest.mark.parametrize("kind", ["cylinder", "block"])
def test_hand_contact_grasp_matches_the_reference_for_10_s(kind: str) -> None:
    obj = ContactObject(kind=kind, y_m=0.03 if kind == "cylinder" else 0.025)
    (a, audit_a), (b, audit_b) = (_hand_grasp(e, obj, 10_000) for e in ENGINES)
    assert a.t_s == pytest.approx(10.0) and a.t_s == b.t_s
    for fa, fb in zip(a.fingers, b.fingers, strict=True):
        assert fb.pads[0] + fb.pads[2] > 0.5  # in contact: the contact law is exercised
        for u, v in zip((fa.prox_rad, fa.motor_rad, *fa.flex_rad),
                        (fb.prox_rad, fb.motor_rad, *fb.flex_rad), strict=True):
            assert abs(u - v) <= TOL_RAD
    assert a.preshape_rad == pytest.approx(b.preshape_rad, abs=TOL_RAD)
    assert np.allclose(audit_a, audit_b, rtol=1e-9, atol=1e-15) and max(audit_b[0]) > 0.0


def test_single_steps_match_with_delay_and_hung_weight() -> None:
    p = default_finger_params()
    obj = ContactObject(kind="cylinder")
    a = b = initial_finger_state(p)
    for k in range(3000):
        cmd = MotorCommand("position", JOINT_RATIO * (0.0 if k < 200 else 1.5))
        a = finger_step(a, cmd, p, obj, EFFECTS, 1e-3)
        b = compiled_finger_step(b, cmd, p, obj, EFFECTS, 1e-3)
    assert a.pads[0] + a.pads[2] > 0.0 and a.command == b.command
    assert max(abs(u - v) for u, v in zip(a.flex_rad, b.flex_rad, strict=True)) <= TOL_RAD
    for _ in range(2000):
        a = hung_weight_step(a, p, 9.8, 1e-3, EFFECTS)
        b = compiled_hung_weight_step(b, p, 9.8, 1e-3, EFFECTS)
    assert abs(a.prox_rad - b.prox_rad) <= TOL_RAD and a.prox_rad > 0.3


def test_the_comparison_can_fail() -> None:
    """The tolerance sees a physics difference: a 1e-6 change of one constant breaks it."""
    p = default_finger_params()
    q = replace(p, k_tendon_n_per_m=p.k_tendon_n_per_m * (1.0 + 1e-6))
    obj = ContactObject(kind="cylinder")
    a = b = initial_finger_state(p)
    for _ in range(1500):
        cmd = MotorCommand("position", 2.0)
        a = finger_step(a, cmd, p, obj, EffectSet(), 1e-3)
        b = compiled_finger_step(b, cmd, q, obj, EffectSet(), 1e-3)
    assert abs(a.motor_rad - b.motor_rad) > TOL_RAD


def test_unknown_engine_is_a_one_line_error() -> None:
    with pytest.raises(UserInputError, match="unknown physics engine"):
        engine("fortran")


def test_bench_loops_follow_the_python_benchmark() -> None:
    """``teleop bench sim``'s compiled loop runs the same controller and physics."""
    import math

    from sim.bench_compiled import finger_arrays, finger_loop
    from sim.compiled_kernel import X_PHI, X_TH

    p = default_finger_params()
    obj = ContactObject(kind="cylinder")
    st = initial_finger_state(p)
    w = 2.0 * math.pi * 0.5
    for k in range(1200):
        sp = 0.7 - 0.7 * math.cos(w * k * 1e-3)
        goal = JOINT_RATIO * (sp + 0.2 * (sp - st.prox_rad))
        st = finger_step(st, MotorCommand("position", goal), p, obj, EffectSet(), 1e-3)
    x, k_, dsegs, o, e = finger_arrays()
    finger_loop(1200, x, k_, dsegs, o, e, 1e-3)
    assert st.pads[0] + st.pads[2] > 5.0 and st.prox_rad > 0.1
    assert abs(x[X_PHI] - st.prox_rad) <= TOL_RAD and abs(x[X_TH] - st.motor_rad) <= TOL_RAD


@pytest.mark.parametrize("exp", ["force-blocks", "position"])
def test_diagnosis_simulation_matches_the_reference(exp: str) -> None:
    """``simulate_dynamic`` (the fit's inner loop): delay line, excluded rows and restarts
    held at the measured angle (holding, or at a measured effort), sub-stepping and a coarser
    step, on both engines; the force-blocks case with the motor's friction part on the speed
    law (``speed_law_fraction``, which the fit refines)."""
    from sim.finger_dynamic import dynamic_data, simulate_dynamic

    p = default_finger_params()
    rec = run_experiment(ExperimentSpec(exp, duration_s=10.0, rate_hz=1000.0), p,
                         ContactObject(), EffectSet()).recording
    if exp == "force-blocks":
        p = replace(p, speed_law_fraction=0.6)
    data = dynamic_data(rec, "motor_angle_rad")
    active = np.ones(len(data.t_s), dtype=bool)
    active[4000:4500] = False
    cut = replace(data, active=active, restart_goal_rad=np.full(len(data.t_s), 0.5))
    # restarting at a measured effort (a hand recording's load) instead of the holding one
    loaded = replace(cut, restart_effort_units=np.full(len(data.t_s), -150.0))
    eff = EffectSet(dead_time=0.03, backlash=0.02, stiction=1.0, sensor_offset=0.01)
    for d, steps in ((data, (2e-3, 5e-4)), (cut, (2e-3, 5e-4)), (loaded, (2e-3,))):
        for dt in steps:
            a, b = (simulate_dynamic(p, eff, d, dt, e) for e in ENGINES)
            assert np.array_equal(np.isnan(a), np.isnan(b))
            assert np.nanmax(np.abs(a - b)) <= TOL_RAD and np.ptp(b[~np.isnan(b)]) > 0.1
    assert np.isnan(a[4100]) and not np.isnan(a[4600])


@pytest.mark.parametrize("exp", ["force-blocks", "position"])
def test_an_input_lead_matches_the_reference(exp: str) -> None:
    """``DynamicData.input_lead`` (the next row's command over the last part of each row: a
    logged, sampled set-point) on both engines, with a dead time's delay line and an
    excluded stretch: the same to 1e-9 rad, and it moves the finger (earlier)."""
    from sim.finger_dynamic import dynamic_data, simulate_dynamic

    p = default_finger_params()
    rec = run_experiment(ExperimentSpec(exp, duration_s=10.0, rate_hz=100.0), p,
                         ContactObject(), EffectSet()).recording
    data = dynamic_data(rec, "motor_angle_rad")
    active = np.ones(len(data.t_s), dtype=bool)
    active[400:450] = False
    cut = replace(data, active=active, restart_goal_rad=np.full(len(data.t_s), 0.5))
    for d in (data, cut):
        for lead in (0.3, 1.0):
            for eff in (EffectSet(), EffectSet(dead_time=0.03)):
                a, b = (simulate_dynamic(p, eff, replace(d, input_lead=lead), 2e-3, e)
                        for e in ENGINES)
                assert np.array_equal(np.isnan(a), np.isnan(b))
                assert np.nanmax(np.abs(a - b)) <= TOL_RAD
                held = simulate_dynamic(p, eff, d, 2e-3, "compiled")
                assert np.nanmax(np.abs(b - held)) > 1e-5


@pytest.mark.parametrize("exp", ["force-blocks", "position"])
def test_a_shaft_ripple_matches_the_reference(exp: str) -> None:
    """The position-periodic shaft force (``shaft_ripple_*``, what ``teleop diagnose`` fits for
    cogging) on both engines: the same to 1e-9 rad, and it moves the finger."""
    from sim.finger_dynamic import dynamic_data, simulate_dynamic

    p = default_finger_params()
    rec = run_experiment(ExperimentSpec(exp, duration_s=10.0, rate_hz=1000.0), p,
                         ContactObject(), EffectSet()).recording
    data = dynamic_data(rec, "motor_angle_rad")
    q = replace(p, shaft_ripple_sin_n=1.2, shaft_ripple_cos_n=-0.5, shaft_ripple_per_rad=31.4)
    a, b = (simulate_dynamic(q, EffectSet(), data, 2e-3, e) for e in ENGINES)
    assert np.max(np.abs(a - b)) <= TOL_RAD
    plain = simulate_dynamic(p, EffectSet(), data, 2e-3, "python")
    assert np.max(np.abs(b - plain)) > 1e-3


def test_warm_up_loads_the_signature_the_hand_loop_uses() -> None:
    """No first-call stall: after ``SimHand.start`` the reads compile nothing new, even with
    integer times and goals (a new argument type would compile a new machine code)."""
    from sim.compiled_runs import run_hand
    from sim.sim_hand import SimHand
    from teleop.config import load_config
    from teleop.messages import HandCommand, HandMode, Header

    hand = SimHand(load_config(None, ["hand.sim.engine=compiled"]).hand, seed=0)
    hand.start()
    before = list(run_hand.signatures)
    hand.apply(HandCommand(Header(1, 0.0, 0.0), (1, 1, 1), 0, HandMode.POSITION, (0, 0, 0)))
    hand.read(1)
    hand.read(1.5)
    assert hand.state.t_s == pytest.approx(1.5) and before
    assert list(run_hand.signatures) == before


@pytest.mark.parametrize("effects", [EffectSet(), EFFECTS], ids=["nominal", "all-effects"])
def test_weight_equilibrium_matches_the_reference(effects: EffectSet) -> None:
    from sim.finger import weight_equilibrium

    p = default_finger_params()
    for force in (15.7, 9.8, 4.9):
        a, b = (weight_equilibrium(p, force, effects=effects, engine_name=e) for e in ENGINES)
        assert abs(a[0] - b[0]) <= TOL_RAD and abs(a[1] - b[1]) <= TOL_RAD
    assert a[1] > 0.1 and weight_equilibrium(p, 15.7, engine_name="python")[0] > 2.0
