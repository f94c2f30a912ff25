"""Library terms on the output-error path (:mod:`teleop.diagnose.propose`)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from teleop.diagnose.diagnose import DiagnoseOptions, diagnose

sys.path.insert(0, str(Path(__file__).parent))

from indep_axis import make_closed_loop  # noqa: E402


@pytest.mark.slow
def test_no_library_term_for_what_the_simulation_itself_may_have_made() -> None:
    """A clean closed-loop drive (independent generator, seed 3: a PD controller's logged
    force in, position out, the nominal's friction stated 10 % off).  The output-error path's
    nominal fit leaves 1.87x the noise, and that model's simulation moves 6.5x the noise when
    its step is made 8x finer: the residual is within what the simulation itself may have
    made, and ``sin(189 x)`` (a 0.033 rad wave, held-out gain 69 %) was proposed for it.
    Now nothing is named or proposed.  Mutant watched failing: the gate on the noise alone
    (``step_error`` returning 0) proposes ``sin(189.06 x)`` again."""
    rec, nominal = make_closed_loop(3, 0.0, 0.0)
    d = diagnose([rec], DiagnoseOptions(nominal, "torque_nm", "angle_rad"))
    keys = [k for p in d.proposed for k in p.keys]
    assert d.effects == () and keys == [], (d.effects, keys)
