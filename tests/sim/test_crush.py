"""A yielding object (sim.crush): the dent's law, its energy (the audit counts the work that
crushes it, and the object never gives that back), and the compiled engine held to the Python
reference on a grasp that crushes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_compiled_engine import EFFECTS, _hand_grasp

from sim.audit import object_work_j, pad_depths
from sim.compiled import pack_object
from sim.compiled_crush import mean_yield_force as kernel_mean_yield_force
from sim.contact import ContactObject
from sim.crush import mean_yield_force, yield_pad_spring
from sim.engine import ENGINES
from sim.experiments import ExperimentSpec, run_experiment
from sim.finger import MotorCommand, default_finger_params, finger_step, initial_finger_state
from teleop.effects import EffectSet

TOL_RAD = 1e-9
F_Y = 3.0
CRUSHABLE = ContactObject(kind="cylinder", stiffness_n_per_m=2000.0, damping_n_s_per_m=0.0,
                          yield_force_n=F_Y)


def test_the_skin_is_held_at_the_yield_level_by_a_dent_that_never_shrinks() -> None:
    obj = ContactObject(kind="cylinder", yield_force_n=F_Y, yield_hardening_n_per_m=500.0)
    crush = 0.0
    depths = [*np.linspace(0.0, 0.011, 60), *np.linspace(0.011, 0.0, 60)]
    for d in depths:
        before = crush
        force, _, _, crush = yield_pad_spring(obj, 0.5, d, crush)
        assert crush >= before
        assert force <= 0.5 * (F_Y + 500.0 * crush) * (1.0 + 1e-12)
        assert force == pytest.approx(0.5 * 2000.0 * max(d - crush, 0.0), abs=1e-12)
    # loaded to 11 mm: the dent where the hardened yield level meets the spring, kept after
    assert crush == pytest.approx((2000.0 * 0.011 - F_Y) / 2500.0)
    assert yield_pad_spring(obj, 1.0, 0.5 * crush, crush)[0] == 0.0  # inside the dent: no pull


def test_the_audit_mean_force_is_exact_across_the_kinks() -> None:
    """Entering the dent, yielding and reaching the core in one step: the mean force's work
    equals the integral of the law along the step (fine quadrature), both engines alike."""
    obj = ContactObject(kind="cylinder", yield_force_n=F_Y, yield_hardening_n_per_m=300.0,
                        core_depth_m=0.004)
    c0, d0, d1 = 0.001, 0.0005, 0.0045
    ds = np.linspace(d0, d1, 200_001)
    crush = c0
    forces = []
    for d in ds:
        f, _, _, crush = yield_pad_spring(obj, 1.0, float(d), crush)
        forces.append(f)
    exact = float(np.trapezoid(forces, ds))
    work = mean_yield_force(obj, 1.0, d0, c0, 1.0, d1) * (d1 - d0)
    assert work == pytest.approx(exact, rel=1e-8)
    assert kernel_mean_yield_force(pack_object(obj), 1.0, d0, c0, 1.0, d1) * (d1 - d0) == work


def _press_and_withdraw(obj: ContactObject) -> tuple[float, float, float, tuple[float, float]]:
    """One finger closed into ``obj`` and opened again: (delivered, taken) by the audit, the
    net work of the contact forces the physics step applied (finger side), the final dents."""
    fp = default_finger_params()
    st = initial_finger_state(fp)
    before = pad_depths(st, fp, obj)
    out = taken = applied = 0.0
    for goal, n in ((1.6, 3000), (0.0, 3000)):
        for _ in range(n):
            st = finger_step(st, MotorCommand("position", goal), fp, obj, EffectSet(), 1e-3)
            after = pad_depths(st, fp, obj)
            w = object_work_j(before, after, obj, 1e-3)
            applied += st.pads[0] * (after[1] - before[1]) + st.pads[2] * (after[3] - before[3])
            before = after
            out, taken = out + max(w, 0.0), taken + max(-w, 0.0)
    assert before[1] == 0.0 and before[3] == 0.0  # withdrawn: out of contact again
    return out, taken, applied, st.crush_m


def test_a_withdrawn_finger_leaves_the_plastic_work_in_the_object() -> None:
    """The audit integrates the law's force times the depth change; the plastic work is the
    yield force times the dents' growth; the finger side is the contact force the step applied
    (start-of-step dent, linearly implicit) times the depth change.  They agree (the step's
    within 3 %), and the work stays in the object, whereas the elastic object returns all."""
    out, taken, applied, (c_p, c_d) = _press_and_withdraw(CRUSHABLE)
    assert min(c_p, c_d) > 1e-3  # both pads crushed the object by more than a millimetre
    plastic = F_Y * (c_p + c_d)
    assert out - taken == pytest.approx(plastic, rel=1e-9)
    assert applied == pytest.approx(plastic, rel=0.03)
    assert taken > 0.0  # the skin's elastic energy did come back
    hardening = ContactObject(kind="cylinder", damping_n_s_per_m=0.0, yield_force_n=F_Y,
                              yield_hardening_n_per_m=400.0)
    out, taken, applied, (c_p, c_d) = _press_and_withdraw(hardening)
    plastic = sum(F_Y * c + 0.5 * 400.0 * c * c for c in (c_p, c_d))
    assert out - taken == pytest.approx(plastic, rel=1e-9)
    assert applied == pytest.approx(plastic, rel=0.03)
    elastic = ContactObject(kind="cylinder", damping_n_s_per_m=0.0)
    out, taken, applied, dents = _press_and_withdraw(elastic)
    assert dents == (0.0, 0.0) and out > 0.01
    assert out - taken == pytest.approx(0.0, abs=1e-6 * out)
    assert abs(applied) < 0.03 * out


def test_a_damped_yielding_object_takes_more_than_the_plastic_work() -> None:
    damped = ContactObject(kind="cylinder", damping_n_s_per_m=5.0, yield_force_n=F_Y)
    out, taken, _, (c_p, c_d) = _press_and_withdraw(damped)
    assert out - taken > F_Y * (c_p + c_d) > 0.0


@pytest.mark.parametrize("kind", ["cylinder", "block"])
def test_a_crushing_grasp_matches_the_reference(kind: str) -> None:
    obj = ContactObject(kind=kind, y_m=0.03 if kind == "cylinder" else 0.025,
                        yield_force_n=2.5, yield_hardening_n_per_m=100.0)
    (a, audit_a), (b, audit_b) = (_hand_grasp(e, obj, 4000, release=True) for e in ENGINES)
    for fa, fb in zip(a.fingers, b.fingers, strict=True):
        assert max(fb.crush_m) > 2e-3  # the grasp crushed: the yielding law is exercised
        for u, v in zip((fa.prox_rad, fa.motor_rad, *fa.flex_rad, *fa.crush_m),
                        (fb.prox_rad, fb.motor_rad, *fb.flex_rad, *fb.crush_m), strict=True):
            assert abs(u - v) <= TOL_RAD
    assert np.allclose(audit_a, audit_b, rtol=1e-9, atol=1e-15)
    if kind == "cylinder":  # (the block's pads reach its core, whose energy comes back)
        net = sum(audit_b[0]) - sum(audit_b[1])
        assert net > 0.5 * sum(audit_b[0])  # opened again: most of the work stayed in dents


def test_elastic_default_has_no_dent() -> None:
    st, _ = _hand_grasp("compiled", ContactObject(kind="cylinder"), 2000, release=True)
    assert all(f.crush_m == (0.0, 0.0) for f in st.fingers)
    assert math.isclose(st.fingers[0].pads[0] + st.fingers[0].pads[2], 0.0)  # opened


def test_the_grasp_experiment_on_a_yielding_object_matches_the_reference() -> None:
    """The finger loop (``teleop sim grasp``: the compiled run packs the dents in its state
    array and back) against the Python reference, with the effects on."""
    obj = ContactObject(kind="cylinder", yield_force_n=2.0)
    runs = [run_experiment(ExperimentSpec("grasp", duration_s=6.0), default_finger_params(),
                           obj, EFFECTS, engine_name=e) for e in ENGINES]
    a, b = (r.recording for r in runs)
    for col in ("motor_angle_rad", "proximal_angle_rad", "distal_angle_rad"):
        assert np.max(np.abs(a.column(col) - b.column(col))) <= TOL_RAD, col
    assert np.max(np.abs(a.data - b.data)) <= 1e-6  # pressures too
    peak = [float(np.max(b.column(f"pressure_{i}"))) for i in range(9)]
    assert max(peak[:5]) > 500.0  # the proximal pad crushed the skin down to the core
    assert max(peak[5:]) < 100.0  # the distal pad's skin yielded (elastic cylinder: 904)
