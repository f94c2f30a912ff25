"""The object's rigid core: the servo's full torque cannot push a finger through the object
(the soft skin alone lets it: kept as the mutant), in both engines alike."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from sim import finger as fm
from sim.audit import pad_depths
from sim.compiled import pack_object
from sim.compiled_kernel import mean_spring_force as kernel_mean
from sim.compiled_kernel import pad_spring as kernel_spring
from sim.contact import ContactObject, mean_spring_force, pad_spring
from sim.engine import engine
from teleop.effects import EffectSet

CYL = ContactObject(kind="cylinder")  # the default object: 20 mm, 2000 N/m skin
FULL = fm.MotorCommand(mode="position", goal_rad=4.2, speed_rad_s=0.0, torque_limit=1.0)


def _squeeze(obj: ContactObject, engine_name: str, seconds: float = 3.0):
    """Full servo torque towards full closure for ``seconds``; (deepest pad depth over the
    run, final outputs)."""
    eng = engine(engine_name)
    p = fm.default_finger_params()
    st = fm.initial_finger_state(p)
    deepest = 0.0
    for _ in range(int(seconds / 0.1)):
        st, _ = eng.run_finger(st, [FULL] * 100, [1e-3] * 100, p, obj, EffectSet(),
                               [False] * 101)
        d = pad_depths(st, p, obj)
        deepest = max(deepest, d[1], d[3])
    return deepest, fm.finger_outputs(st, p, obj, EffectSet())


@pytest.mark.parametrize("engine_name", ["compiled", "python"])
def test_full_torque_does_not_push_the_finger_through_the_object(engine_name: str) -> None:
    _, free = _squeeze(ContactObject(kind="none"), engine_name, 1.5)
    deepest, held = _squeeze(CYL, engine_name)
    assert held.tendon_force_n > 150.0  # the servo really is pulling with everything it has
    assert deepest < CYL.core_depth_m + 1.5e-3  # into the skin, stopped at the core
    assert any(held.contact)  # still touching at the end
    assert held.proximal_rad < 0.5 * free.proximal_rad  # the object holds the base link
    # the mutant: a skin without a core lets the finger through
    deepest, through = _squeeze(replace(CYL, core_stiffness_n_per_m=0.0), engine_name)
    assert deepest > CYL.radius_m  # past the centre
    assert through.proximal_rad > held.proximal_rad + 0.2


def test_both_engines_share_the_spring_law_to_the_bit() -> None:
    o = pack_object(CYL)
    for scale in (1.0, 0.37):
        for depth in np.linspace(0.0, 0.03, 61):
            assert tuple(kernel_spring(o, scale, depth)) == pad_spring(CYL, scale, depth)
    for d0, d1 in ((0.002, 0.004), (0.011, 0.013), (0.014, 0.010), (0.02, 0.021)):
        assert kernel_mean(o, 1.0, d0, 0.8, d1) == mean_spring_force(CYL, 1.0, d0, 0.8, d1)


def test_the_core_spring_is_continuous_and_stiffer_past_the_core() -> None:
    dc = CYL.core_depth_m
    below, k_below = pad_spring(CYL, 1.0, dc - 1e-9)
    above, k_above = pad_spring(CYL, 1.0, dc + 1e-9)
    assert above == pytest.approx(below, abs=1e-3)  # no jump in force at the core
    assert k_below == CYL.stiffness_n_per_m
    assert k_above == CYL.stiffness_n_per_m + CYL.core_stiffness_n_per_m
    # the mean force over a step across the core integrates the work exactly
    d0, d1 = dc - 2e-3, dc + 1e-3
    work = mean_spring_force(CYL, 1.0, d0, 1.0, d1) * (d1 - d0)

    def energy(d: float) -> float:
        return 0.5 * (CYL.stiffness_n_per_m * d * d
                      + CYL.core_stiffness_n_per_m * max(d - dc, 0.0) ** 2)

    assert work == pytest.approx(energy(d1) - energy(d0), rel=1e-12)
