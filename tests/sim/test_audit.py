"""The physical energy audit: operator-port work from the operator model, object-port work
from the finger geometry and the contact law (sim.audit), checked against energy stored."""

from __future__ import annotations

import math

import pytest

from sim.audit import object_work_j, pad_depths
from sim.contact import ContactObject
from sim.finger import MotorCommand, default_finger_params, finger_step, initial_finger_state
from sim.operator import OperatorParams, OperatorState, operator_step
from sim.params import FingerParams
from sim.readout import distal_origin
from sim.state import FingerState
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


def _bed_energy_j(st: FingerState, fp: FingerParams, obj: ContactObject,
                  n: int = 4001) -> float:
    """The energy a block holds, from the contact law's own definition, integrated here: a
    bed of springs along each pad, ``k`` (and past the core's depth ``k_core``) per unit of
    pad fraction, each element pressed to its own depth (the pad is straight, so the depth
    is linear along it); quadrature over ``n`` points, independent of sim.audit."""
    po = fp.pad_offset_m
    c, s = math.cos(st.prox_rad), math.sin(st.prox_rad)
    x, y, ca, sa = distal_origin(st, fp)
    ax, ay = x - sa * po, y + ca * po
    pads = (((0.010, po), (fp.proximal_rigid_m, po)),
            ((ax, ay), (ax + ca * fp.distal_length_m, ay + sa * fp.distal_length_m)))
    total = 0.0
    for (x0, y0), (x1, y1) in pads:
        d0 = s * x0 + c * y0 - obj.y_m  # depth (world y past the face) at the two ends
        d1 = s * x1 + c * y1 - obj.y_m
        h = 1.0 / (n - 1)
        for i in range(n):
            d = d0 + (d1 - d0) * i * h
            if d <= 0.0:
                continue
            e = 0.5 * obj.stiffness_n_per_m * d * d
            e += 0.5 * obj.core_stiffness_n_per_m * max(d - obj.core_depth_m, 0.0) ** 2
            total += e * (0.5 if i in (0, n - 1) else 1.0) * h
    return total


def test_pressing_a_block_stores_what_the_audit_counts() -> None:
    """Without contact damping the net work on a block is the energy its bed of springs
    holds, whatever the pad's tilt: the distal pad meets the face tip first, tilted, and is
    held there by the servo (0.188 J).  The audit counted force times the change of the
    pressed part's mean depth until 2026-11-28 and read 0.104 J here."""
    fp = default_finger_params()
    obj = ContactObject(kind="block", damping_n_s_per_m=0.0)
    st = initial_finger_state(fp)
    before = pad_depths(st, fp, obj)
    net = 0.0
    for _ in range(3000):
        st = finger_step(st, MotorCommand("position", 2.5 * 1.42), fp, obj, EffectSet(), 1e-3)
        after = pad_depths(st, fp, obj)
        net += object_work_j(before, after, obj, 1e-3)
        before = after
    stored = _bed_energy_j(st, fp, obj)
    assert stored > 0.05  # really pressed
    assert math.isclose(net, stored, rel_tol=0.02)
