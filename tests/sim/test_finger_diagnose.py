"""The finger as a ``teleop diagnose`` nominal model (static weight test)."""

from __future__ import annotations

import numpy as np

from sim.finger import weight_equilibrium
from sim.finger_diagnose import FingerStaticModel
from sim.params import default_finger_params
from teleop.effects import EffectSet


def test_static_model_is_the_weight_equilibrium_plus_the_sensor_offset() -> None:
    p = default_finger_params()
    model = FingerStaticModel(p, 0.2)
    forces = np.array([9.8, 15.7])
    t = np.arange(2.0)
    y = model.simulate(model.initial(), EffectSet(), t, forces)
    assert np.allclose(y, [weight_equilibrium(p, f)[0] for f in forces])
    y2 = model.simulate(model.initial(), EffectSet(sensor_offset=0.05), t, forces)
    assert np.allclose(y2 - y, 0.05)
    lo, hi = model.bounds()
    assert np.all(lo < model.initial()) and np.all(model.initial() < hi)
    assert set(model.candidates()) <= {"sensor_offset", "nonlinear_stiffness", "gravity"}
