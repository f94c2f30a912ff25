"""Each path's ``without`` (:func:`teleop.diagnose.engine.own_share`): the fit with one effect
removed and everything else held is the same model simulated with that effect absent."""

from __future__ import annotations

import math

import numpy as np
import pytest

from teleop.diagnose import engine
from teleop.diagnose.diagnose import DiagnoseOptions, diagnose
from teleop.diagnose.fit import simulate
from tests.teleop.diagnose.indep_axis import make


@pytest.mark.slow
def test_the_axis_path_removes_the_effect_and_holds_the_rest(
        monkeypatch: pytest.MonkeyPatch) -> None:
    seen = []
    own = engine.own_share

    def spy(path, current, name, f):  # type: ignore[no-untyped-def]
        alone = own(path, current, name, f)
        seen.append((path, name, f, alone))
        return alone

    monkeypatch.setattr(engine, "own_share", spy)
    c = make("coulomb_friction", 501)  # the axis batch's first Coulomb case (seed 500 + 1)
    d = diagnose([c.recording], DiagnoseOptions(c.nominal, "torque_nm", "angle_rad"))
    assert d.effects and d.effects[0].name == "coulomb_friction"
    path, name, f, alone = next(s for s in seen if s[1] == "coulomb_friction")
    assert alone.effects == () and "effect:coulomb_friction" not in alone.names
    # the same as the fitted model with the friction at its absent value, 0
    theta = [0.0 if k == "effect:coulomb_friction" else v for k, v in zip(f.names, f.theta,
                                                                      strict=True)]
    r = simulate(f.names, theta, path.data) - path.data.y
    assert math.isclose(alone.rss, float(r @ r), rel_tol=1e-9)
    assert np.array_equal(alone.y_fit, simulate(f.names, theta, path.data))
    # a friction that is there carries its score on its own
    assert engine.score(path, alone, f) > 100


class _Spring:
    """y = u / k + offset: a static model written here."""

    name = "spring"

    def param_names(self) -> tuple[str, ...]:
        return ("k",)

    def initial(self) -> np.ndarray:
        return np.array([2.0])

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array([0.5]), np.array([10.0])

    def candidates(self) -> tuple[str, ...]:
        return ("sensor_offset", "gravity")

    def simulate(self, theta, effects, t_s, u):  # type: ignore[no-untyped-def]
        return u / theta[0] + effects.sensor_offset + effects.gravity * np.sin(u)


def test_the_static_path_removes_the_effect_and_holds_the_rest() -> None:
    from teleop.diagnose.generic import StaticPath, _fit
    from teleop.effects import EffectSet

    u = np.linspace(0.5, 5.0, 12)
    y = u / 2.5 + 0.2
    m = _Spring()
    path = StaticPath(m, np.arange(12.0), u, y, {}, {"sensor_offset": (-1.0, 1.0),
                                                      "gravity": (-1.0, 1.0)})
    f = _fit(m, path.t, u, y, ("gravity", "sensor_offset"), np.array([2.0, 0.1, 0.1]),
             np.array([0.5, -1.0, -1.0]), np.array([10.0, 1.0, 1.0]))
    alone = path.without(f, "sensor_offset", f)
    assert alone.effects == ("gravity",)
    expect = m.simulate(f.x[:1], EffectSet(gravity=float(f.x[1])), path.t, u) - y
    assert np.array_equal(alone.residual, expect)
    assert math.isclose(alone.rss, float(expect @ expect))
    assert alone.rss > 100 * max(f.rss, 1e-12)   # the offset is in the data
