"""An effect the final (joint) model holds at its absent value is not named (issue 14).

A stub simulated model, linear in two effects, whose single fit of ``backlash`` sticks where it
started (a local minimum, as a real output-error fit can): ``coulomb_friction`` explains most
of the recording first; then the joint fit with ``backlash`` moves the friction to 0, its
absent value.  Only ``backlash`` may be reported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from teleop.diagnose.select_sim import at_absent_value, diagnose_dynamic
from tests.teleop.diagnose.test_select_sim import Data, Fit

N = 400
T = np.linspace(0.0, 8.0, N)
S_B = np.sin(2.0 * T) + 0.5 * np.sin(5.3 * T)          # backlash's signature (per unit)
S_C = np.cos(7.1 * T) * np.exp(-0.1 * T)               # what friction adds besides
S_A = 0.3 * S_B + 0.05 * S_C                           # friction's signature (per unit)
SHAPES = {"coulomb_friction": S_A, "backlash": S_B}
CANDS = {"coulomb_friction": ((0.3, 1.0, 2.0, 4.0), (0.0, 20.0)),
         "backlash": ((0.01, 0.03, 0.1), (0.0, 0.5))}


@dataclass
class StubModel:
    data: Data
    dt_s: float = 1e-3

    def candidates(self) -> dict[str, tuple[tuple[float, ...], tuple[float, float]]]:
        return CANDS

    def nominal_start(self) -> tuple[float, ...]:
        return (1.0,)

    def floor(self) -> tuple[float, float]:
        return 1e-3, 0.0

    def run(self, theta: object, effects: tuple[tuple[str, float], ...]) -> np.ndarray:
        return sum((v * SHAPES[n] for n, v in effects), np.zeros(N))

    def rss(self, y: np.ndarray) -> float:
        r = (y - self.data.y)[self.data.split()[0]]
        return float(r @ r)

    def residual(self, f: Fit) -> np.ndarray:
        return (f.y - self.data.y)[self.data.split()[0]]

    def finish(self, theta: tuple[float, ...], effects: tuple[tuple[str, float], ...]
               ) -> Fit:
        y = self.run(theta, effects)
        te = self.data.split()[1]
        r = (y - self.data.y)[te]
        return Fit(tuple(theta), tuple(effects), self.rss(y), float(r @ r), y)

    def fit(self, theta0: tuple[float, ...], effects: tuple[tuple[str, float], ...]
            ) -> Fit:
        names = [n for n, _ in effects]
        if names in ([], ["backlash"]):  # nothing to fit / stuck where it started
            return self.finish(theta0, effects)
        tr = self.data.split()[0]
        a = np.column_stack([SHAPES[n][tr] for n in names])
        lo = [CANDS[n][1][0] for n in names]
        hi = [CANDS[n][1][1] for n in names]
        x = optimize.lsq_linear(a, self.data.y[tr], bounds=(lo, hi), method="bvls").x
        return self.finish(theta0, tuple(zip(names, x.tolist(), strict=True)))


def _model() -> StubModel:
    rng = np.random.default_rng(3)
    return StubModel(Data(T, np.zeros(N), 0.3 * S_B + 1e-3 * rng.standard_normal(N)))


def test_an_effect_fitted_away_by_the_joint_model_is_not_named() -> None:
    model = _model()
    d = diagnose_dynamic(model)
    # the path went through friction first (else this test proves nothing) ...
    assert "coulomb_friction" in dict(d.scores) and d.ranking[0][0] == "coulomb_friction"
    # ... the joint model holds it at 0, and only backlash is named
    assert [c[0] for c in d.chosen] == ["backlash"]
    assert d.chosen[0][1] == np.float64(0.3) or math.isclose(d.chosen[0][1], 0.3, rel_tol=1e-2)
    assert len(d.verdicts) == len(d.chosen)
    assert dict(d.final.effects) == {"backlash": d.chosen[0][1]}


def test_absent_values_per_effect() -> None:
    assert at_absent_value("coulomb_friction", 0.0, (0.0, 20.0))
    assert at_absent_value("coulomb_friction", 1e-5, (0.0, 20.0))
    assert not at_absent_value("coulomb_friction", 0.05, (0.0, 20.0))
    assert at_absent_value("actuator_gain", 1.0, (0.2, 3.0))
    assert not at_absent_value("actuator_gain", 1.2, (0.2, 3.0))
    assert at_absent_value("actuator_saturation", math.inf, (0.2, 30.0))
    assert not at_absent_value("actuator_saturation", 30.0, (0.2, 30.0))
