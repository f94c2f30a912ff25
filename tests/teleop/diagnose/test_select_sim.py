"""The simulated-model selection loop on a model that is not the finger (no ``sim/``): a
first-order lag driven by steps, its nominal time constant refined, catalog effects tried."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from teleop.diagnose.select_sim import diagnose_dynamic

NOISE = 0.002
CANDS = {"sensor_offset": ((-0.1, 0.1), (-1.0, 1.0)), "actuator_gain": ((0.8, 1.2), (0.2, 3.0))}


@dataclass(frozen=True)
class Data:
    t: np.ndarray
    u: np.ndarray
    y: np.ndarray

    @property
    def keep(self) -> np.ndarray:
        return np.arange(len(self.t))

    def split(self) -> tuple[np.ndarray, np.ndarray]:
        i = np.arange(len(self.t))
        test = (i // 10) % 4 == 3
        return i[~test], i[test]


@dataclass(frozen=True)
class Fit:
    theta: tuple[float, ...]
    effects: tuple[tuple[str, float], ...]
    rss: float
    rss_test: float
    y: np.ndarray


def lag(t: np.ndarray, u: np.ndarray, tau: float, offset: float = 0.0,
        gain: float = 1.0) -> np.ndarray:
    y = np.zeros(len(t))
    for i in range(1, len(t)):
        a = math.exp(-(t[i] - t[i - 1]) / tau)
        y[i] = a * y[i - 1] + (1 - a) * gain * u[i - 1]
    return y + offset


@dataclass(frozen=True)
class LagModel:
    data: Data
    dt_s: float = 0.01
    floor_rad: float = NOISE

    def candidates(self) -> dict[str, tuple[tuple[float, ...], tuple[float, float]]]:
        return CANDS

    def nominal_start(self) -> tuple[float, ...]:
        return (0.2,)

    def floor(self) -> tuple[float, float]:
        return self.floor_rad, 0.0

    def run(self, theta: tuple[float, ...], effects: tuple[tuple[str, float], ...]
            ) -> np.ndarray:
        e = dict(effects)
        return lag(self.data.t, self.data.u, float(theta[0]), e.get("sensor_offset", 0.0),
                   e.get("actuator_gain", 1.0))

    def rss(self, y: np.ndarray) -> float:
        tr, _ = self.data.split()
        return float(np.sum((y - self.data.y)[tr] ** 2))

    def residual(self, f: Fit) -> np.ndarray:
        tr, _ = self.data.split()
        return (f.y - self.data.y)[tr]

    def finish(self, theta: tuple[float, ...], effects: tuple[tuple[str, float], ...]) -> Fit:
        y = self.run(theta, effects)
        _, te = self.data.split()
        return Fit(tuple(theta), effects, self.rss(y),
                   float(np.sum((y - self.data.y)[te] ** 2)), y)

    def bounds(self, name: str) -> tuple[float, float]:
        return CANDS[name][1]

    def fit(self, theta0: tuple[float, ...], effects: tuple[tuple[str, float], ...]) -> Fit:
        names = [n for n, _ in effects]
        tr, _ = self.data.split()

        def resid(x: np.ndarray) -> np.ndarray:
            eff = tuple(zip(names, x[1:].tolist(), strict=True))
            return (self.run((x[0],), eff) - self.data.y)[tr]

        lo = [0.16] + [self.bounds(n)[0] for n in names]  # the time constant within +-20 %
        hi = [0.24] + [self.bounds(n)[1] for n in names]
        x0 = np.clip([theta0[0], *[v for _, v in effects]], lo, hi)
        x = optimize.least_squares(resid, x0, bounds=(lo, hi)).x
        return self.finish((float(x[0]),), tuple(zip(names, x[1:].tolist(), strict=True)))


def _data(offset: float, seed: int) -> Data:
    rng = np.random.default_rng(seed)
    t = np.arange(400) * 0.01
    u = np.repeat(rng.uniform(-1, 1, 20), 20)
    return Data(t, u, lag(t, u, 0.21, offset) + rng.normal(0, NOISE, len(t)))


def test_the_loop_names_an_offset_on_a_model_that_is_not_the_finger() -> None:
    d = diagnose_dynamic(LagModel(_data(0.05, 1)))
    assert [c[0] for c in d.chosen] == ["sensor_offset"]
    assert abs(d.chosen[0][1] - 0.05) < 0.005
    assert d.verdicts[0].accepted and d.warning is None


def test_the_loop_names_nothing_on_a_clean_recording() -> None:
    d = diagnose_dynamic(LagModel(_data(0.0, 2)))
    assert d.chosen == () and d.warning is None
    # with the floor understated the loop tries the candidates: the shared rule refuses them
    d = diagnose_dynamic(LagModel(_data(0.0, 2), floor_rad=NOISE / 3))
    assert d.chosen == () and d.rejected


def test_every_chosen_value_is_the_final_joint_models() -> None:
    """Two effects: the first one's value is reported as it stands in the final (joint) model
    (what ``--write-params`` writes and the after-fit uses), not as the first step fitted it
    without the second (the axis path's contract, ``select.select_oe``)."""
    rng = np.random.default_rng(3)
    t = np.arange(400) * 0.01
    u = np.repeat(rng.uniform(0, 1, 20), 20)   # one-signed: the step-1 gain absorbs the offset
    d = diagnose_dynamic(LagModel(Data(t, u, lag(t, u, 0.21, 0.05, 1.5)
                                       + rng.normal(0, NOISE, len(t)))))
    final = dict(d.final.effects)
    assert sorted(n for n, _, _ in d.chosen) == ["actuator_gain", "sensor_offset"]
    for name, value, _ in d.chosen:
        assert value == final[name], (name, value, final[name])
    assert abs(final["actuator_gain"] - 1.5) < 0.05 and abs(final["sensor_offset"] - 0.05) < 0.01
