"""Free-air tactile noise must not reach the trigger (lockstep, the grid's soft operator).

The simulated hand's cells are noisy (sigma 1.5 units, as the TakkTile's); the largest of 27
noisy cells sits a few units above zero.  Displayed through the force map it was a 0.02-0.1 N
buzz that the soft operator's hand resonated with (a 0.1 mm trigger ripple at 5 Hz that the
stability classifier, rightly, flagged).  The transparency layer's deadband removes it; the
mutant without it shows the ripple again.
"""

from __future__ import annotations

import numpy as np
import pytest

from teleop.analysis.stability import classify_run
from teleop.analysis.sweep import SweepPoint, point_config, point_duration_s
from teleop.config import load_config

pytestmark = pytest.mark.slow


def _run(deadband: float):
    from services.lockstep import run_lockstep
    from teleop.analysis.sweep_signals import signals_from_lockstep

    cfg = load_config(None, [f"controller.transparency.pressure_deadband={deadband}"])
    pc = point_config(cfg, SweepPoint("two-layer", 0.0, 0.0, 0.0, 11, "soft", "free-air"))
    res = run_lockstep(pc, point_duration_s(pc, 5.0))
    return res, classify_run(signals_from_lockstep(res, pc))


def test_free_air_noise_gives_no_force_and_a_still_trigger() -> None:
    res, m = _run(load_config(None).controller.transparency.pressure_deadband)
    late = res.t_s > 2.5
    assert np.max(res.max_pressure[late]) > 0  # the cells are noisy
    assert np.max(np.abs(res.displayed_force_n[late])) == 0.0
    assert m.stable, m.reason


def test_mutant_without_the_deadband_buzzes_the_trigger() -> None:
    res, m = _run(0.0)
    late = res.t_s > 2.5
    assert np.std(res.displayed_force_n[late]) > 0.005
    trig = next(o for o in m.oscillations if o.name == "trigger_m")
    assert trig.amplitude > 0.5 * trig.threshold and trig.frequency_hz > 2.0
