"""The motor's speed-dependent friction law (``FingerParams.speed_law_fraction``, issue 14).

At fraction 0 the finger is today's (the lockstep digests hold that bit for bit); at any
fraction the unloaded pull still reproduces Table 4.1, the law goes through the datasheet's
no-load speed, and the compiled step follows the Python reference to 1e-9 rad.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from sim.contact import ContactObject
from sim.engine import ENGINES
from sim.experiments import ExperimentSpec, run_experiment
from sim.finger import NO_EFFECTS, default_finger_params
from sim.params import TABLE_4_1_SLOPES, speed_friction_units
from teleop.effects import EffectSet

P = default_finger_params()
TOL_RAD = 1e-9


def test_speed_law_goes_through_table_4_1_and_the_no_load_speed() -> None:
    for units, speed in TABLE_4_1_SLOPES:
        assert speed_friction_units(P, speed)[0] == pytest.approx(units - P.motor_coulomb_units)
        assert speed_friction_units(P, -speed)[0] == pytest.approx(P.motor_coulomb_units - units)
    assert speed_friction_units(P, 5.76)[0] == pytest.approx(1023.0 - 5.0)
    # finite, positive slope at rest (the linearly implicit step needs it) and continuity
    g0, s0 = speed_friction_units(P, 0.0)
    assert g0 == 0.0 and 0.0 < s0 < 1e4
    for w in (0.06733, 0.1781, 0.424):
        lo, hi = (speed_friction_units(P, w * (1 + d))[0] for d in (-1e-9, 1e-9))
        assert hi == pytest.approx(lo, rel=1e-6)
    # the slope is the derivative
    for w in (0.03, 0.1, 0.3, 2.0, 8.0):
        h = 1e-6 * w
        num = (speed_friction_units(P, w + h)[0] - speed_friction_units(P, w - h)[0]) / (2 * h)
        assert speed_friction_units(P, w)[1] == pytest.approx(num, rel=1e-5)


@pytest.mark.parametrize("fraction", [0.5, 1.0])
@pytest.mark.parametrize(("units", "slope"), TABLE_4_1_SLOPES)
def test_pull_unloaded_still_matches_table_4_1(units: float, slope: float,
                                               fraction: float) -> None:
    p = replace(P, speed_law_fraction=fraction)
    res = run_experiment(ExperimentSpec("pull-unloaded", units=units), p, ContactObject(),
                         NO_EFFECTS)
    assert float(res.summary["motor_velocity_rad_s"]) == pytest.approx(slope, rel=0.05)


def test_the_laws_differ_in_transients() -> None:
    """Same steady state, different dynamics: the runs move apart by several times the noise,
    most in position mode (else the fit could not tell the fraction)."""
    for name, apart_rad in (("force-blocks", 0.005), ("position", 0.05)):
        spec = ExperimentSpec(name, duration_s=6.0)
        a, b = (run_experiment(spec, replace(P, speed_law_fraction=f), ContactObject(),
                               EffectSet()).recording.column("motor_angle_rad")
                for f in (0.0, 1.0))
        assert np.max(np.abs(a - b)) > apart_rad, name


@pytest.mark.parametrize("fraction", [0.4, 1.0])
@pytest.mark.parametrize("name", ["force-blocks", "position", "pull-unloaded"])
def test_compiled_step_matches_the_reference_with_the_speed_law(name: str,
                                                                fraction: float) -> None:
    p = replace(P, speed_law_fraction=fraction)
    eff = EffectSet(coulomb_friction=0.5, dead_time=0.02, backlash=0.01)
    spec = ExperimentSpec(name, duration_s=6.0)
    a, b = (run_experiment(spec, p, ContactObject(kind="cylinder"), eff,
                           engine_name=e).recording for e in ENGINES)
    for col in ("motor_angle_rad", "proximal_angle_rad", "distal_angle_rad"):
        assert np.max(np.abs(a.column(col) - b.column(col))) <= TOL_RAD, col
    assert np.ptp(b.column("motor_angle_rad")) > 0.05


def test_the_compiled_comparison_sees_the_fraction() -> None:
    """The compiled step reads the fraction: 0.4 against 0.4 + 1e-6 fails the tolerance."""
    spec = ExperimentSpec("force-blocks", duration_s=3.0)
    a = run_experiment(spec, replace(P, speed_law_fraction=0.4), ContactObject(), EffectSet(),
                       engine_name="compiled").recording
    b = run_experiment(spec, replace(P, speed_law_fraction=0.4 + 1e-6), ContactObject(),
                       EffectSet(), engine_name="python").recording
    assert np.max(np.abs(a.column("motor_angle_rad") - b.column("motor_angle_rad"))) > TOL_RAD
