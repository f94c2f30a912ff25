"""A delay is fitted from its two best screening points (``select_sim._fit_delay``).

Its residual is rugged (whole physics steps; the refined finger bends with it), so one start
stops in the nearest dip.  Case 714 of the independent finger batch (``tests/sim/
indep_finger.py``: its own physics and integrator, a force-mode recording concealing a 98 ms
command delay): the grid's 60 ms point screens a hair better than its 100 ms point, and the
fit from 60 ms stopped at 75 ms, where a 96 ms lag fits better and was named (measured).
"""

from __future__ import annotations

import pytest

from sim.finger_dynamic import FingerDynamicModel, dynamic_data
from sim.params import default_finger_params
from teleop.diagnose import select_sim
from tests.sim.indep_finger import make

SEED = 714


def _chosen() -> tuple[tuple[str, float, float], ...]:
    case = make("dead_time", SEED)
    model = FingerDynamicModel(default_finger_params(),
                               dynamic_data(case.recording, "motor_angle_rad"))
    return select_sim.diagnose_dynamic(model).chosen


@pytest.mark.slow
def test_a_delay_between_grid_points_is_named_not_read_as_a_lag(
        monkeypatch: pytest.MonkeyPatch) -> None:
    truth = make("dead_time", SEED).value
    chosen = _chosen()
    assert [name for name, _, _ in chosen] == ["dead_time"]
    assert abs(chosen[0][1] - truth) < 0.005

    # the mutant fits the delay from its best screening point only: the lag is named
    monkeypatch.setattr(select_sim, "DELAY_STARTS", 1)
    assert _chosen()[0][0] == "actuator_lag"
