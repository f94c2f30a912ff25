"""Physics outside the catalog on the closed-loop (equation-error) path: a drive under a
discrete PD position controller with a cogging torque, generated here by its own code (a 1 kHz
controller holding its command, the plant stepped by RK4 at 10 kHz, encoder noise and
quantisation, nominal parameters stated a few per cent off)."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from teleop.diagnose.diagnose import DiagnoseOptions, diagnose
from teleop.diagnose.model import AxisNominal
from teleop.diagnose.report import to_json, to_text
from teleop.recording import Recording

RATE_HZ = 1000
SUB = 10
COUNT_RAD = 2 * math.pi / 4096
M, C, FC = 0.8, 0.6, 0.3
PERIOD_RAD = 0.25
COG_NM = 1.5
BUMP_RAD = 0.3


def drive(seed: int, cog_nm: float, duration_s: float = 8.0, asym_nm: float = 0.0,
          coulomb_nm: float = 0.0, bump_nm: float = 0.0, cog_until_s: float = math.inf
          ) -> Recording:
    """``asym_nm``: Coulomb friction that acts only while moving in the positive direction;
    ``coulomb_nm``: Coulomb friction beyond the nominal's (both directions); ``bump_nm``: a
    hard spot, a torque ``bump_nm exp(-((x - BUMP_RAD) / 0.05)^2)`` (in no library family);
    ``cog_until_s``: the cogging acts only before this time (a detent that disengages)."""
    rng = np.random.default_rng(seed)
    n = int(duration_s * RATE_HZ)
    t = np.arange(n) / RATE_HZ
    f = rng.uniform(0.1, 0.8, 4)
    ph = rng.uniform(0, 2 * math.pi, 4)
    ref = sum(np.sin(2 * math.pi * fi * t + p) for fi, p in zip(f, ph, strict=True)) / 2
    kp, kd = 60.0 * M, 8.0 * M
    w = 2 * math.pi / PERIOD_RAD

    def acc(x: float, v: float, u: float, cog: float) -> float:
        fr = (C * v + (FC + coulomb_nm) * math.tanh(v / 1e-3)
              + asym_nm * (0.5 + 0.5 * math.tanh(v / 1e-3)))
        bump = bump_nm * math.exp(-(((x - BUMP_RAD) / 0.05) ** 2))
        return (u - fr + cog * math.sin(w * x) - bump) / M

    x = v = 0.0
    xs, us = np.empty(n), np.empty(n)
    h = 1.0 / (RATE_HZ * SUB)
    for i in range(n):
        u = kp * (ref[i] - x) - kd * v          # held for the whole period
        xs[i], us[i] = x, u
        cog = cog_nm if t[i] < cog_until_s else 0.0
        for _ in range(SUB):
            k1x, k1v = v, acc(x, v, u, cog)
            k2x, k2v = v + 0.5 * h * k1v, acc(x + 0.5 * h * k1x, v + 0.5 * h * k1v, u, cog)
            k3x, k3v = v + 0.5 * h * k2v, acc(x + 0.5 * h * k2x, v + 0.5 * h * k2v, u, cog)
            k4x, k4v = v + h * k3v, acc(x + h * k3x, v + h * k3v, u, cog)
            x += h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x)
            v += h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
    y = np.round((xs + 3e-4 * rng.standard_normal(n)) / COUNT_RAD) * COUNT_RAD
    return Recording.from_columns({"t_s": t, "torque_nm": us, "angle_rad": y})


NOMINAL = AxisNominal(("inertia", "viscous", "coulomb"), (M * 1.07, C * 0.92, FC * 1.1), 0.3)


def _diagnose(rec: Recording):  # noqa: ANN202
    return diagnose([rec], DiagnoseOptions(NOMINAL, "torque_nm", "angle_rad",
                                           analysis="equation-error"))


def _periodic(d) -> list[tuple[float, list[float]]]:  # noqa: ANN001
    """(wavenumber, coefficients) of the proposed sin/cos terms within 2 % of the cogging's."""
    waves: dict[float, list[float]] = {}
    for p in d.proposed:
        for k, c in zip(p.keys, p.coefs, strict=True):
            if k.startswith("term:sin:") or k.startswith("term:cos:"):
                waves.setdefault(float(k.split(":")[2]), []).append(c)
    w = 2 * math.pi / PERIOD_RAD
    return [(k, cs) for k, cs in waves.items() if abs(k / w - 1) < 0.02]


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2, 4, 5, 6, 7])
def test_cogging_in_closed_loop_data_is_proposed_as_a_position_periodic_term(seed: int) -> None:
    """The periodic term competes with the catalog effects in the same engine call: on every
    drive it wins and no catalog effect is named.  (With terms proposed only where no catalog
    effect was accepted, seeds 2, 4, 5 and 6 named a dead time of 0.01-0.04 s instead, and
    got no term.)  3 s drives keep the test short: wavenumber 24.97-25.15 (truth 25.13),
    amplitude 1.47-1.54 N m (truth 1.5) measured (1.29-1.48 before the equation error's filter
    passes and input alignment were made consistent)."""
    d = _diagnose(drive(seed, COG_NM, 3.0))
    assert d.analysis == "equation-error"
    hits = _periodic(d)
    assert hits, (d.proposed, d.effects)
    amp = math.hypot(*hits[0][1])
    assert abs(amp / COG_NM - 1) < 0.25, amp
    # what the term explains is not also named as a catalog effect
    assert not d.effects, d.effects
    assert d.nrmse_after < 0.5 * d.nrmse_before
    assert d.residual_after.rms_over_noise < 2.0   # measured 0.77-1.19


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2, 4, 5, 6, 7])
def test_cogging_behind_a_catalog_effect_is_named_as_a_periodic_term(seed: int) -> None:
    """A direction-dependent Coulomb level (2 N m, in the catalog) and the cogging: the
    catalog effect wins the first step; the library is then offered on what it leaves (the
    effect kept in the model), by the same engine and rule, and the periodic term is named as
    an equation with units.  Before (library not offered once a catalog effect was named):
    only the unexplained-residual warning (3.8-6.1x the noise).  Measured: wavenumber
    24.98-25.23 (truth 25.13), amplitude 1.46-1.55 N m (truth 1.5), residual 0.83-1.10x,
    level 1.95-2.06 N m in the joint fit with the term."""
    d = _diagnose(drive(seed, COG_NM, 3.0, asym_nm=2.0))
    assert [e.name for e in d.effects] == ["asymmetric_friction"], d.effects
    # its level as it stands in the joint fit with the term (measured 2.00-2.05)
    assert abs(d.effects[0].params[0][1] / 2.0 - 1) < 0.1, d.effects
    hits = _periodic(d)
    assert hits, (d.proposed, d.effects)
    assert abs(math.hypot(*hits[0][1]) / COG_NM - 1) < 0.25, hits
    assert d.residual_after.rms_over_noise < 2.0, d.residual_after
    doc = to_json(d)
    assert not doc["unexplained"], doc["unexplained"]
    eq = doc["proposed"][0]["equation"]
    assert "sin(" in eq and "[N m]" in eq and "rad^-1" in eq, eq


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2, 4, 5, 6, 7])
def test_a_catalog_effect_alone_gets_no_library_term(seed: int) -> None:
    """The same drives without the cogging: the catalog effect, and no library term (the
    library stage after the catalog finds nothing that passes; measured residual
    0.86-1.19x)."""
    d = _diagnose(drive(seed, 0.0, 3.0, asym_nm=2.0))
    assert [e.name for e in d.effects] == ["asymmetric_friction"], d.effects
    assert d.proposed == (), d.proposed


@pytest.mark.slow
def test_physics_outside_the_library_is_warned_about_with_where() -> None:
    """A hard spot at one position (no library family fits it) beside the direction-dependent
    Coulomb level: the catalog effect is named, no term explains the rest, and the report says
    the residual stays above the noise, and where: every span it names passes the spot."""
    d = _diagnose(drive(2, 0.0, 3.0, asym_nm=2.0, bump_nm=10.0))
    assert d.effects and d.effects[0].name == "asymmetric_friction", d.effects
    assert d.residual_after.rms_over_noise > 3.0, d.residual_after   # measured 6.8
    warning = to_json(d)["unexplained"]
    assert warning and "unexplained residual" in warning and "where" in warning, warning
    assert d.unexplained_where
    for w in d.unexplained_where:
        found = re.search(r"position (\S+) to (\S+)", w.why)
        assert found, w.why
        assert float(found[1]) <= BUMP_RAD <= float(found[2]), w


@pytest.mark.slow
def test_clean_closed_loop_data_gets_no_library_term() -> None:
    d = _diagnose(drive(3, 0.0, 3.0))
    assert d.proposed == (), d.proposed
    assert d.effects == (), d.effects


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2, 4])
def test_a_symmetric_extra_coulomb_level_is_named_coulomb_friction(seed: int) -> None:
    """A Coulomb level of 2.3 N m where the nominal states 0.33 N m +-30 %: the drive sticks
    much of the time.  It was named ``actuator_gain``, ``dead_time`` or ``actuator_lag`` with a
    ``u(t - 0.1 s)`` term: ``coulomb_friction`` was never a candidate when the nominal has a
    Coulomb term, though a *stated* one is held to its tolerance and the level beyond it is the
    missing effect (the mutant restoring that exclusion fails here).  Measured: the effect alone,
    nominal 0.429 (its bound) + 1.87-1.91 (truth 2.3 in all), residual 0.76-1.55x."""
    d = _diagnose(drive(seed, 0.0, 3.0, coulomb_nm=2.0))
    assert [e.name for e in d.effects] == ["coulomb_friction"], (d.effects, d.proposed)
    total = dict(d.final_params)["coulomb"] + d.effects[0].params[0][1]
    assert abs(total / (FC + 2.0) - 1) < 0.1, total
    assert d.proposed == (), d.proposed
    assert d.residual_after.rms_over_noise < 2.0, d.residual_after


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2])
def test_cogging_behind_a_symmetric_coulomb_level_is_named(seed: int) -> None:
    """The same drive with the cogging: ``coulomb_friction`` first, then the periodic term on
    what it leaves (before: neither was named)."""
    d = _diagnose(drive(seed, COG_NM, 3.0, coulomb_nm=2.0))
    assert [e.name for e in d.effects] == ["coulomb_friction"], (d.effects, d.proposed)
    hits = _periodic(d)
    assert hits, (d.proposed, d.effects)
    assert abs(math.hypot(*hits[0][1]) / COG_NM - 1) < 0.25, hits


def _sin_terms(d) -> list[str]:  # noqa: ANN001
    return [k for p in d.proposed for k in p.keys if k.startswith("term:sin:")]


def _without_library_holdout(monkeypatch: pytest.MonkeyPatch) -> None:
    """The mutant: a library term's held-out gain taken as perfect (the check dropped)."""
    from teleop.diagnose import select_ee
    from teleop.diagnose.equation_error import EE_EFFECTS
    real = select_ee._ee_holdout

    def no_check(sig, nominal, cur, aug, name, grid, fixed_inertia):  # noqa: ANN001, ANN202
        if name in EE_EFFECTS:
            return real(sig, nominal, cur, aug, name, grid, fixed_inertia)
        return 1.0
    monkeypatch.setattr(select_ee, "_ee_holdout", no_check)


@pytest.mark.slow
@pytest.mark.parametrize(("seed", "coulomb_nm"), [(1, 0.0), (2, 0.0), (1, 2.0), (2, 2.0)])
@pytest.mark.parametrize("mutant", [False, True])
def test_a_library_term_that_does_not_hold_out_is_refused(
        seed: int, coulomb_nm: float, mutant: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """A cogging that disengages at 2.1 s of 3 s (where the held-out part begins): on the
    whole recording a periodic term passes the score (15-55) and the noise gate (residual
    3.5-4.3x), at the first step and (with the 2 N m Coulomb level) after the catalog, but it
    does not hold on the held-out part, which is all the held-out check sees.  Refused, and the
    residual is reported as unexplained.  The mutant (the check dropped, ``mutant=True``)
    accepts the terms on every one of these drives: this case exercises the check."""
    if mutant:
        _without_library_holdout(monkeypatch)
    d = _diagnose(drive(seed, COG_NM, 3.0, coulomb_nm=coulomb_nm, cog_until_s=2.1))
    if mutant:
        assert _sin_terms(d), d.proposed
        return
    assert not _sin_terms(d), d.proposed
    assert d.residual_after.rms_over_noise > 3.0, d.residual_after   # measured 3.5-4.3
    if coulomb_nm:
        assert [e.name for e in d.effects] == ["coulomb_friction"], d.effects
        assert to_json(d)["unexplained"], d.residual_after
    else:
        assert not d.effects, d.effects
        assert "physics outside the catalog" in to_text(d), to_text(d)
