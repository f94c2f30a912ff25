"""The shaft ripple as a fit carries it (``sim/finger_ripple.py``): library pair <-> params."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.finger_ripple import WAVE_MAX_PER_RAD, describe, split, wave_grid
from teleop.diagnose.select_sim_terms import pair
from teleop.effects import EffectSet


def test_a_pair_becomes_the_params_fields_and_the_rest_stays_catalog() -> None:
    eff, rip = split((("coulomb_friction", 0.5), *pair(31.4, 1.2, -0.4)))
    assert eff == EffectSet(coulomb_friction=0.5)
    assert rip == {"shaft_ripple_sin_n": 1.2, "shaft_ripple_cos_n": -0.4,
                   "shaft_ripple_per_rad": 31.4}
    assert split((("dead_time", 0.1),)) == (EffectSet(dead_time=0.1), {})


def test_a_term_the_finger_cannot_carry_is_refused() -> None:
    with pytest.raises(ValueError, match="term:v3"):
        split((("term:v3:0", 1.0),))


def test_the_grid_spans_one_and_a_half_periods_to_the_finest_ripple() -> None:
    g = wave_grid(1.0)
    assert g[0] == pytest.approx(3 * math.pi) and g[-1] < WAVE_MAX_PER_RAD
    assert np.diff(g) == pytest.approx(np.full(len(g) - 1, math.pi / 4))
    assert len(wave_grid(0.0)) == 0 and len(wave_grid(math.nan)) == 0
    assert len(wave_grid(0.05)) == 0   # a shaft that barely moved: nothing to scan


def test_the_equation_states_amplitude_and_period() -> None:
    text = describe(split(pair(20.0, 0.6, -0.8))[1])
    assert "amplitude 1 N" in text and "period 0.314 rad" in text and "- 0.8 cos" in text
