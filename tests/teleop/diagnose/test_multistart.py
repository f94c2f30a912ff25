"""Several starts for the output-error fits (:mod:`teleop.diagnose.multistart`)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from teleop.diagnose import diagnose as diagnose_mod
from teleop.diagnose import engine, multistart, propose, select
from teleop.diagnose.criterion import Verdict
from teleop.diagnose.diagnose import DiagnoseOptions, diagnose
from teleop.diagnose.fit import ModelFit, fit_model
from teleop.diagnose.model import AxisNominal
from teleop.diagnose.multistart import lowest, restarts

sys.path.insert(0, str(Path(__file__).parent))

from indep_axis import make  # noqa: E402


def test_restarts_add_the_centred_alignment_and_the_stated_values() -> None:
    nominal = AxisNominal(("inertia", "viscous"), (2.0, None), 0.3)
    start = {"inertia": 2.5, "viscous": 1.0, "input_shift": -1e-3, "x0_0": 0.0}
    out = restarts(start, nominal)
    assert out[0] == start
    assert {**start, "input_shift": 0.0} in out
    assert {**start, "inertia": 2.0, "input_shift": 0.0} in out
    # nothing to restart: one start
    assert restarts({"inertia": 2.0, "input_shift": 0.0}, nominal) == [
        {"inertia": 2.0, "input_shift": 0.0}]


def _named(seed: int) -> list[str]:
    c = make("coulomb_friction", seed)
    d = diagnose([c.recording], DiagnoseOptions(c.nominal, "torque_nm", "angle_rad"))
    return [e.name for e in d.effects]


@pytest.mark.slow
@pytest.mark.parametrize("mutant", [False, True])
def test_a_fit_stuck_with_the_alignment_at_its_bound_is_restarted(
        mutant: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """Independent-batch case ``coulomb_friction`` seed 178 (Coulomb 7.41): the nominal fit puts
    the input's alignment at its bound (-1 ms) to make up for the missing friction; the Coulomb
    fit started there stopped at 3x the residual of one started at the centre (score 6052
    instead of 7088) and ``gravity`` 1.05 made up the difference (score 1185, a false
    discovery).  With the restarts: ``coulomb_friction`` alone.  The mutant (one start only,
    ``mutant=True``) names a second effect beside it again (gravity, or stiction): this case exercises the restarts."""
    if mutant:
        for mod in (select, diagnose_mod):
            monkeypatch.setattr(mod, "restarts", lambda start, nominal=None: [start])
    named = _named(178)
    if mutant:  # a false discovery beside it again: gravity where it was recorded, stiction
        # on the machine of 2026-11-26 (the optimiser's last digits choose which, not whether)
        assert named[0] == "coulomb_friction" and len(named) > 1, named
    else:
        assert named == ["coulomb_friction"], named


@pytest.mark.slow
def test_one_chosen_effect_is_also_checked_backwards() -> None:
    """Independent-batch case ``cogging`` seed 106 (``7.80 sin(38.70 x)``): after the periodic
    term, ``series_compliance`` was accepted on top of it with score 3107 at its *absent*
    value (stiffness inf): its refit (more iterations, the alignment restarted) improved the
    under-converged model with the term, and the improvement went to the effect.  The
    backward elimination, which refits the model without the effect from the joint fit, ran
    only with two effects or more; now with one too.  Since only the leading candidate is
    restarted (:meth:`select.OEPath.refine`) this case no longer names the effect at all,
    so the elimination's own proof is the test below."""
    c = make("cogging", 106)
    d = diagnose([c.recording], DiagnoseOptions(c.nominal, "torque_nm", "angle_rad"))
    assert not d.effects, d.effects
    waves = [float(k.split(":")[2]) for p in d.proposed for k in p.keys
             if k.startswith("term:sin:")]
    assert any(abs(w / c.wavenumber - 1) < 0.02 for w in waves), (waves, c.wavenumber)


def test_a_single_effect_the_model_does_not_need_is_eliminated(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The mechanism of seed 106 made certain: on a clean recording (independent generator),
    the forward selection is made to accept ``gravity`` from the nominal fit (as an
    under-converged model's refit once got an effect accepted); ``select_oe``'s backward
    elimination refits the model without it and drops it (the removal costs nothing).
    Mutants watched failing: no elimination for a single effect (in ``select_oe`` or in
    ``_prune``) keeps ``gravity``."""
    got: dict[str, object] = {}
    real_oe = select.select_oe

    def capture(path, nom):  # noqa: ANN001, ANN202
        got.setdefault("path", path)
        got.setdefault("nom", nom)
        return real_oe(path, nom)

    monkeypatch.setattr(propose, "select_oe", capture)
    c = make(None, 100)
    assert not diagnose([c.recording], DiagnoseOptions(c.nominal, "torque_nm",
                                                       "angle_rad")).effects
    path, nom = got["path"], got["nom"]
    full = fit_model(path.data, path.nominal, {**nom.as_dict(), "effect:gravity": 0.0},  # type: ignore[attr-defined]
                     ("gravity",), path.opts.max_nfev)  # type: ignore[attr-defined]
    verdict = Verdict(50.0, 2000.0, 0.1, True, "accepted")
    sel = engine.Selection(full, (engine.Step("gravity", full, verdict),), (("gravity", 50.0),),
                           ())
    monkeypatch.setattr(select.engine, "forward", lambda *a, **k: sel)
    final, chosen, _, _ = select.select_oe(path, nom)  # type: ignore[arg-type]
    assert chosen == [], chosen
    assert "effect:gravity" not in final.names


def _fit(rss: float) -> ModelFit:
    return ModelFit((), ("inertia",), (1.0,), (0.1,), rss, 10, np.zeros(10))


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_a_first_fit_with_a_non_finite_residual_is_not_kept(bad: float) -> None:
    """A first start whose fit ends at a NaN residual was kept against every later finite one
    (``f.rss < nan`` is false): the fit of lowest *finite* residual wins, in any order."""
    assert lowest([_fit(bad), _fit(3.0), _fit(2.0)]).rss == 2.0
    assert lowest([_fit(3.0), _fit(bad), _fit(2.0)]).rss == 2.0
    assert lowest([_fit(2.0), _fit(3.0), _fit(bad)]).rss == 2.0
    assert math.isnan(lowest([_fit(math.nan), _fit(math.nan)]).rss)  # none finite: the first


def test_fit_best_skips_a_non_finite_first_fit(monkeypatch: pytest.MonkeyPatch) -> None:
    """``fit_best`` itself (the fits faked by their start): NaN first, then finite ones."""
    rss = iter([math.nan, 5.0, 4.0])
    monkeypatch.setattr(multistart, "fit_model", lambda *a, **k: _fit(next(rss)))
    got = multistart.fit_best(None, None, [{}, {}, {}], (), 1)  # type: ignore[arg-type]
    assert got.rss == 4.0
