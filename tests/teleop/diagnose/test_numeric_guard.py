"""Regression: a candidate whose simulation overflows is disqualified, never a traceback.

``teleop diagnose /tmp/fb_clean.csv --model axis --input motor_cmd_units --output
motor_angle_rad`` (a ``teleop sim force-blocks --seed 3`` recording) died with an OverflowError in
the Stribeck term ``exp(-(v / vs) ** 2)`` while scanning the stiction candidate.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from teleop.diagnose import axis_model, fit
from teleop.diagnose.diagnose import diagnose
from teleop.diagnose.model import parse_nominal
from teleop.diagnose.results import DiagnoseOptions
from teleop.diagnose.synth import INPUT_COL, OUTPUT_COL, make_case
from teleop.effects import EffectSet


def test_stribeck_term_at_huge_velocity_over_tiny_stribeck_velocity_does_not_raise() -> None:
    t = np.arange(0, 0.2, 1e-3)
    p = axis_model.AxisParams(1.0, 0.0, 1.0, stribeck_velocity=1e-200)
    x = axis_model.simulate_axis(t, np.full(len(t), 1e3), p, EffectSet(stiction=5.0),
                                 x0=0.0, v0=1e160)
    assert len(x) == len(t)
    # it diverges (|v| > 1e12) and says so with NaN, from the point it blew up
    assert math.isnan(x[-1])


def test_stiction_far_above_the_stribeck_velocity_is_just_coulomb() -> None:
    # with |v| >> vs the Stribeck term vanishes: stiction leaves the sliding motion unchanged
    t = np.arange(0, 0.05, 1e-3)
    p = axis_model.AxisParams(1.0, 0.0, 0.0, stribeck_velocity=1e-6)
    a = axis_model.simulate_axis(t, None, p, EffectSet(coulomb_friction=1.0), v0=10.0)
    b = axis_model.simulate_axis(t, None, p, EffectSet(coulomb_friction=1.0, stiction=3.0),
                                 v0=10.0)
    assert np.allclose(a, b, atol=1e-12)


def test_a_candidate_whose_simulation_raises_is_disqualified(
        monkeypatch: pytest.MonkeyPatch) -> None:
    real = axis_model.simulate_axis

    def flaky(t, u, p, eff=EffectSet(), *a, **k):  # type: ignore[no-untyped-def]
        if eff.stiction > 0 or eff.nonlinear_stiffness != 0:
            raise OverflowError(34, "Numerical result out of range")
        return real(t, u, p, eff, *a, **k)

    monkeypatch.setattr(fit, "simulate_axis", flaky)
    case = make_case(("coulomb_friction",), "random", seed=4242, duration_s=4.0)
    p = case.params
    nominal = parse_nominal(f"inertia={p.inertia},viscous,stiffness={p.stiffness}", 0.1)
    d = diagnose([case.recording], DiagnoseOptions(nominal, INPUT_COL, OUTPUT_COL,
                                                   analysis="output-error"))
    assert d.effects and d.effects[0].name == "coulomb_friction"
    assert not {"stiction", "nonlinear_stiffness"} & {e.name for e in d.effects}
    # a failed simulation counts as a diverged one: it ranks below the nominal model
    assert all(b < 0 for n, b in d.ranking if n in ("stiction", "nonlinear_stiffness"))
