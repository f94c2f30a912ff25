"""The physical energy audit: operator-port work from the operator model, object-port work
from the finger geometry and the contact law (sim.audit), checked against energy stored."""

from __future__ import annotations

import math

import pytest

from sim.audit import object_work_j, pad_depths
from sim.contact import ContactObject
from sim.finger import MotorCommand, default_finger_params, finger_step, initial_finger_state
from sim.operator import OperatorParams, OperatorState, operator_step
from teleop.effects import EffectSet


def _op(**kw: float) -> OperatorParams:
    base = dict(mass_kg=0.05, stiffness_n_per_m=500.0, damping_n_s_per_m=6.0, travel_m=0.025,
                force_max_n=8.0, resolution_m=0.0, close_s=0.0, ramp_s=0.5, hold_s=10.0,
                release_s=0.5, closed_fraction=1.0, repeat=False)
    base.update(kw)
    return OperatorParams(**base)  # type: ignore[arg-type]


def test_operator_port_work_is_force_times_displacement() -> None:
    p = _op()
    s = OperatorState()
    for _ in range(400):  # a constant resisting force while the operator closes
        s = operator_step(s, p, 3.0, 1e-3)
    assert s.x_m > 0.005
    assert s.delivered_j == 0.0
    assert math.isclose(s.taken_j, 3.0 * s.x_m, rel_tol=1e-9)


def test_operator_port_work_pushing_the_finger_back_is_delivered() -> None:
    p = _op(stiffness_n_per_m=50.0, ramp_s=0.01)
    s = OperatorState(x_m=0.02)
    x0 = s.x_m
    for _ in range(300):  # 8 N pushes the trigger open against a soft finger
        s = operator_step(s, p, 8.0, 1e-3)
    assert s.x_m < x0
    assert math.isclose(s.delivered_j - s.taken_j, 8.0 * (x0 - s.x_m), rel_tol=1e-9)


def _press(obj: ContactObject, goal_rad: float, steps: int) -> tuple[float, float, float]:
    """Drive one finger to ``goal_rad`` and hold; (delivered, taken, stored at the end)."""
    fp = default_finger_params()
    st = initial_finger_state(fp)
    before = pad_depths(st, fp, obj)
    out = taken = 0.0
    cmd = MotorCommand("position", goal_rad)
    for _ in range(steps):
        st = finger_step(st, cmd, fp, obj, EffectSet(), 1e-3)
        after = pad_depths(st, fp, obj)
        w = object_work_j(before, after, obj, 1e-3)
        before = after
        out, taken = out + max(w, 0.0), taken + max(-w, 0.0)
    k, kc, dc = obj.stiffness_n_per_m, obj.core_stiffness_n_per_m, obj.core_depth_m
    stored = sum(0.5 * s * (k * d * d + kc * max(d - dc, 0.0) ** 2)
                 for s, d in ((before[0], before[1]), (before[2], before[3])))
    return out, taken, stored


def test_free_air_takes_no_energy() -> None:
    assert _press(ContactObject(kind="none"), 2.0, 1500) == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("stiffness", [300.0, 2000.0])
def test_pressing_a_cylinder_stores_what_the_audit_counts(stiffness: float) -> None:
    """Without contact damping the net work is the spring energy in the object (the elastic
    part is trapezoidal on each side of the core: exact for that piecewise-linear spring; the
    soft object is pressed into its core); with damping it is more, never less."""
    elastic = ContactObject(kind="cylinder", stiffness_n_per_m=stiffness, damping_n_s_per_m=0.0)
    out, taken, stored = _press(elastic, 1.6, 4000)
    assert stored > 1e-4  # really in contact
    assert math.isclose(out - taken, stored, rel_tol=1e-6)
    damped = ContactObject(kind="cylinder", stiffness_n_per_m=stiffness, damping_n_s_per_m=5.0)
    out, taken, stored = _press(damped, 1.6, 4000)
    assert out - taken > stored


def test_release_gives_back_the_stored_energy() -> None:
    fp = default_finger_params()
    obj = ContactObject(kind="cylinder", stiffness_n_per_m=2000.0, damping_n_s_per_m=5.0)
    st = initial_finger_state(fp)
    before = pad_depths(st, fp, obj)
    out = taken = 0.0
    for goal, n in ((1.6, 3000), (0.0, 3000)):
        for _ in range(n):
            st = finger_step(st, MotorCommand("position", goal), fp, obj, EffectSet(), 1e-3)
            after = pad_depths(st, fp, obj)
            w = object_work_j(before, after, obj, 1e-3)
            before = after
            out, taken = out + max(w, 0.0), taken + max(-w, 0.0)
    assert before[1] == 0.0 and before[3] == 0.0  # out of contact again
    assert taken > 0.5 * out  # the object's spring pushed back most of it
    assert out - taken >= -1e-9  # a passive object never gives more than it got
