"""Which service events are alarms (printed by a live service) and which are warnings."""

from __future__ import annotations

from services.starve_alarm import starve_message
from services.telemetry import event_level, is_alarm


def test_guard_alarms_are_printed_watchdogs_and_faults_only_logged() -> None:
    alarms = ["unseen contact: 3 finger(s) stalled with silent tactile cells",
              "yielding contact: 1 finger(s) crushing or sliding", starve_message(1.5)]
    for text in alarms:
        assert is_alarm(text) and event_level(text) == "WARN"
    for text in ["watchdog: no force command, force ramps to zero",
                 "hand fault: servo 2 overload"]:  # every tick while it lasts
        assert not is_alarm(text) and event_level(text) == "WARN"
    info = "passivity layer limiting the set-points"
    assert not is_alarm(info) and event_level(info) == "INFO"
