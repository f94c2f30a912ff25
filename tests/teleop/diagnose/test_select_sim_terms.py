"""A position-periodic term as one more candidate of the simulated-model path
(:mod:`teleop.diagnose.select_sim_terms`), on a model that is not the finger: a first-order
lag whose output is pulled by ``a sin(w y) + b cos(w y)``, written here."""

from __future__ import annotations

import math
from dataclasses import dataclass
from dataclasses import field as dataclass_field

import numpy as np
import pytest

from teleop.diagnose.library import PERIODIC, Term
from teleop.diagnose.select_sim import SimPath, diagnose_dynamic
from teleop.diagnose.select_sim_terms import pair, screen, without_pair
from tests.teleop.diagnose.test_select_sim import CANDS, NOISE, Data, LagModel

W_TRUE = 25.0
A_TRUE = 0.03


def rippled_lag(t: np.ndarray, u: np.ndarray, tau: float, offset: float = 0.0,
                gain: float = 1.0, a: float = 0.0, b: float = 0.0, w: float = 0.0
                ) -> np.ndarray:
    y = np.zeros(len(t))
    for i in range(1, len(t)):
        k = math.exp(-(t[i] - t[i - 1]) / tau)
        pull = a * math.sin(w * y[i - 1]) + b * math.cos(w * y[i - 1]) if w else 0.0
        y[i] = k * y[i - 1] + (1 - k) * (gain * u[i - 1] - pull)
    return y + offset


@dataclass(frozen=True)
class RippleModel(LagModel):
    """The lag model of ``test_select_sim`` that can carry a sin/cos pair."""

    ripple_probe: float = 0.03

    def bounds(self, name: str) -> tuple[float, float]:
        return (-0.1, 0.1) if Term.is_key(name) else CANDS[name][1]

    def ripple_waves(self) -> np.ndarray:
        span = float(np.ptp(self.data.y))
        return np.arange(2 * math.pi * 1.5 / span, 40.0, math.pi / (4 * span))

    def run(self, theta: tuple[float, ...], effects: tuple[tuple[str, float], ...]
            ) -> np.ndarray:
        e = dict(effects)
        amp = {Term.parse(n).kind: (v, Term.parse(n).const) for n, v in effects
               if Term.is_key(n)}
        a, w = amp.get("sin", (0.0, 0.0))
        b, _ = amp.get("cos", (0.0, 0.0))
        return rippled_lag(self.data.t, self.data.u, float(theta[0]),
                           e.get("sensor_offset", 0.0), e.get("actuator_gain", 1.0), a, b, w)


def _data(seed: int, a: float) -> Data:
    rng = np.random.default_rng(seed)
    t = np.arange(600) * 0.01
    u = np.repeat(rng.uniform(-1, 1, 30), 20)
    y = rippled_lag(t, u, 0.21, a=a, b=0.1 * a, w=W_TRUE)
    return Data(t, u, y + rng.normal(0, NOISE, len(t)))


def test_a_periodic_pull_is_found_as_a_term_not_a_catalog_effect() -> None:
    d = diagnose_dynamic(RippleModel(_data(1, A_TRUE)))
    assert d.chosen == () and d.term_verdict is not None and d.term_verdict.accepted
    (ks, a), (kc, b) = d.terms
    assert Term.parse(ks).kind == "sin" and Term.parse(kc).kind == "cos"
    assert Term.parse(ks).const == Term.parse(kc).const
    assert abs(Term.parse(ks).const - W_TRUE) < 0.05 * W_TRUE
    assert abs(a - A_TRUE) < 0.1 * A_TRUE and abs(b - 0.1 * A_TRUE) < 0.1 * A_TRUE
    assert d.warning is None


def test_the_term_is_not_proposed_on_a_clean_recording() -> None:
    d = diagnose_dynamic(RippleModel(_data(2, 0.0), floor_rad=NOISE / 3))
    assert d.chosen == () and d.terms == ()


def test_the_scanned_wavenumber_counts_as_a_parameter() -> None:
    m = RippleModel(_data(1, A_TRUE))
    path = SimPath(m, 2, 2.0, None, m.nominal_start(), NOISE, 450, 150)
    base = m.finish(m.nominal_start(), (("sensor_offset", 0.0),))
    f = m.finish(m.nominal_start(), (("sensor_offset", 0.0), *pair(W_TRUE, A_TRUE, 0.0)))
    assert path.k_added(base, f) == 3
    assert path.k_added(f, f) == 0
    alone = path.without(base, PERIODIC, f)
    assert alone.effects == (("sensor_offset", 0.0),) == without_pair(f.effects)
    assert np.array_equal(alone.y, m.run(m.nominal_start(), (("sensor_offset", 0.0),)))


def test_the_scan_finds_the_true_wavenumber() -> None:
    m = RippleModel(_data(3, A_TRUE))
    nom = m.fit(m.nominal_start(), ())
    w, a, b, rss, _ = screen(m, nom)[0]
    assert abs(w - W_TRUE) < 0.05 * W_TRUE and rss < 0.2 * nom.rss


def test_no_scan_when_a_catalog_effect_already_leaves_the_floor(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """An offset explains the recording to the noise: the costly wavenumber scan is skipped
    (a term could beat the offset only by fitting the noise); with a periodic pull it runs."""
    import teleop.diagnose.select_sim as select_sim

    calls = []
    real = select_sim.fit_pair

    def spy(model, current, progress):  # type: ignore[no-untyped-def]
        calls.append(current)
        return real(model, current, progress)

    monkeypatch.setattr(select_sim, "fit_pair", spy)
    rng = np.random.default_rng(4)
    t = np.arange(600) * 0.01
    u = np.repeat(rng.uniform(-1, 1, 30), 20)
    offset = Data(t, u, rippled_lag(t, u, 0.21, offset=0.05) + rng.normal(0, NOISE, len(t)))
    d = diagnose_dynamic(RippleModel(offset))
    assert [c[0] for c in d.chosen] == ["sensor_offset"] and calls == []
    diagnose_dynamic(RippleModel(_data(1, A_TRUE)))
    assert calls


@dataclass(frozen=True)
class MappedModel(RippleModel):
    """The ripple model with a ``map`` of its own that evaluates the jobs last first (as
    threads may finish them) and counts them."""

    calls: list[int] = dataclass_field(default_factory=list)

    def map(self, fn, items):  # type: ignore[no-untyped-def]
        self.calls.append(len(items))
        done = {i: fn(x) for i, x in reversed(list(enumerate(items)))}
        return [done[i] for i in range(len(items))]


def test_a_model_with_its_own_map_gets_every_batch_through_it_and_the_same_answer() -> None:
    """The engine hands independent simulations and fits to the model's ``map`` (the finger
    runs them on every core); the answer must not depend on the order they are done in."""
    data = _data(1, A_TRUE)
    plain = diagnose_dynamic(RippleModel(data))
    mapped_model = MappedModel(data)
    mapped = diagnose_dynamic(mapped_model)
    assert sum(mapped_model.calls) > 100  # the scan, the screening grids, the fits
    assert mapped.chosen == plain.chosen and mapped.terms == plain.terms
    assert mapped.final.rss == plain.final.rss


@dataclass(frozen=True)
class WideModel(RippleModel):
    """The ripple model scanning up to 100 (rad^-1 of its output) and telling the engine
    where the pull acts (its measured output), so the periodogram start can be tried."""

    def ripple_waves(self) -> np.ndarray:
        span = float(np.ptp(self.data.y))
        return np.arange(2 * math.pi * 1.5 / span, 100.0, math.pi / (4 * span))

    def ripple_position(self) -> np.ndarray:
        return self.data.y


def _many_periods(w: float, a: float) -> Data:
    rng = np.random.default_rng(3)
    t = np.arange(600) * 0.01
    u = np.repeat(rng.uniform(-1, 1, 30), 20)
    y = rippled_lag(t, u, 0.21, a=a, b=0.3 * a, w=w)
    return Data(t, u, y + rng.normal(0, NOISE, len(t)))


def test_over_many_periods_a_periodogram_start_joins_the_probe_dips_and_the_fits_decide(
        ) -> None:
    """The lag's response to its pull is a transient, not a shifted rest, so here the
    periodogram's dip is wrong (about 41) and the probes' is right: the periodogram start
    must be one more start, never a replacement for the probes over many periods."""
    data = _many_periods(60.0, 0.03)
    model = WideModel(data)
    assert float(np.ptp(data.y)) * 60.0 / (2 * math.pi) > 8.0  # many periods
    nom = model.finish((0.21,), ())
    starts = screen(model, nom)
    assert [s[4] for s in starts].count("periodogram") == 1
    assert sum(s[4] == "probes" for s in starts) == 3
    d = diagnose_dynamic(model)
    (ks, a), _ = d.terms
    assert abs(Term.parse(ks).const - 60.0) < 0.01 * 60.0 and abs(a - 0.03) < 0.1 * 0.03


def test_no_periodogram_start_when_the_range_holds_few_periods() -> None:
    """Scanned only up to 5 periods over the range: the probes alone."""
    @dataclass(frozen=True)
    class Narrow(WideModel):
        def ripple_waves(self) -> np.ndarray:
            return super().ripple_waves()[:20]  # up to ~5 periods of the range

    model = Narrow(_data(1, A_TRUE))
    span = float(np.ptp(model.data.y))
    assert max(model.ripple_waves()) * span / (2 * math.pi) < 8.0
    starts = screen(model, model.finish((0.21,), ()))
    assert starts and all(s[4] == "probes" for s in starts)
    wide = WideModel(_data(1, A_TRUE))
    assert "periodogram" in [s[4] for s in screen(wide, wide.finish((0.21,), ()))]


def test_the_wavenumber_of_a_periodogram_start_is_polished_by_simulation() -> None:
    """Over many periods a wavenumber a fraction of a scan step off drifts out of phase: the
    polish moves it towards the truth and the fit improves."""
    from teleop.diagnose.select_sim_terms import _polish_wave

    model = WideModel(_many_periods(60.0, 0.03))
    step = float(np.diff(model.ripple_waves())[0])
    off = 60.0 - 0.6 * step
    f = model.fit((0.21,), pair(off, 0.03, 0.009))
    g = _polish_wave(model, f, off, step)
    w = Term.parse(g.effects[0][0]).const
    assert abs(w - 60.0) < 0.5 * abs(off - 60.0) and g.rss < f.rss


def test_a_model_with_nothing_to_scan_is_diagnosed_without_a_term() -> None:
    """A shaft that did not move gives no wavenumbers (``wave_grid`` of a zero span): the
    diagnosis goes on without the term (it raised IndexError when the scan's step was taken
    of the empty grid)."""
    @dataclass(frozen=True)
    class Still(RippleModel):
        def ripple_waves(self) -> np.ndarray:
            return np.zeros(0)

    d = diagnose_dynamic(Still(_data(1, A_TRUE)))
    assert d.terms == () and d.term_verdict is None
