"""Proof on recordings the project did not generate (`indep_axis.py`: own RK45 integrator,
smooth Coulomb law, own inputs, noise and 12-bit quantisation, nominal inertia and stiffness
5-20 % off the truth), concealed effects of random magnitude, clean recordings, and a
position-periodic cogging torque outside the catalog.  Rates are over the whole batch."""

from __future__ import annotations

import functools

import pytest
from indep_axis import IndepCase, make  # tests/teleop/analysis/indep_axis.py

from teleop.analysis.diagnose import DiagnoseOptions, Diagnosis, diagnose
from teleop.analysis.report import to_json

CONCEALED = ("coulomb_friction", "dead_time", "sensor_offset", "actuator_gain",
             "actuator_saturation")
PER_CLASS = 3
SEED = 500


@functools.cache
def batch() -> tuple[tuple[IndepCase, Diagnosis], ...]:
    out = []
    for i in range(PER_CLASS):
        for j, name in enumerate((None, *CONCEALED, "cogging")):
            c = make(name, SEED + 10 * i + j)
            out.append((c, diagnose([c.recording],
                                    DiagnoseOptions(c.nominal, "torque_nm", "angle_rad"))))
    return tuple(out)


def _first(d: Diagnosis) -> str | None:
    return d.effects[0].name if d.effects else None


@pytest.mark.slow
def test_concealed_effect_ranked_first_on_independent_recordings() -> None:
    cases = [(c, d) for c, d in batch() if c.concealed in CONCEALED]
    hits = [_first(d) == c.concealed for c, d in cases]
    misses = [(c.concealed, _first(d)) for (c, d), h in zip(cases, hits, strict=True) if not h]
    assert sum(hits) >= 0.9 * len(cases), misses


@pytest.mark.slow
def test_outside_the_catalog_is_never_named_without_the_unexplained_warning() -> None:
    cases = [d for c, d in batch() if c.concealed == "cogging"]
    confident = [[e.name for e in d.effects] for d in cases
                 if d.effects and to_json(d)["unexplained"] is None]
    assert len(confident) <= 0.1 * len(cases), confident


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="issue 14 floor not met: 1/3 clean on this batch; the "
                   "nominal residual stays 1.5-2.4x the noise and friction terms absorb it")
def test_clean_independent_recordings_report_no_effect_at_the_floor() -> None:
    found = [[e.name for e in d.effects] for c, d in batch() if c.concealed is None]
    assert sum(not f for f in found) >= 0.9 * len(found), found


@pytest.mark.slow
@pytest.mark.parametrize(("asym_coulomb", "asym_viscous"), [(0.3, 0.5), (0.0, 0.8)])
def test_closed_loop_direction_dependent_friction_is_found_with_both_levels(
        asym_coulomb: float, asym_viscous: float) -> None:
    from indep_axis import make_closed_loop

    rec, nominal = make_closed_loop(11, asym_coulomb, asym_viscous)
    d = diagnose([rec], DiagnoseOptions(nominal, "torque_nm", "angle_rad"))
    assert d.analysis == "equation-error"
    assert d.effects and d.effects[0].name == "asymmetric_friction", d.effects
    p = dict(d.effects[0].params)
    assert abs(p["asymmetric_friction"] - asym_coulomb) <= 0.05
    assert abs(p["asymmetric_viscous"] - asym_viscous) <= 0.15 * asym_viscous
    assert d.nrmse_after < 0.5 * d.nrmse_before
