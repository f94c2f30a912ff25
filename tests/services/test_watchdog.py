"""Watchdog step: timeout, liveliness, ramps without jumps."""

from __future__ import annotations

import pytest

from services.lockstep import run_lockstep
from services.watchdog import (
    WatchdogParams,
    WatchdogState,
    hand_command_watchdog,
    master_force_watchdog,
    watchdog_step,
)
from teleop.config import load_config

P = WatchdogParams(timeout_s=0.01, down_ramp_s=0.1, up_ramp_s=0.1)
DT = 0.001


def run(state: WatchdogState, t0: float, n: int, got: bool, alive: bool = True
        ) -> tuple[WatchdogState, list[float]]:
    gains = []
    for k in range(n):
        state = watchdog_step(state, P, t0 + k * DT, got, alive, DT)
        gains.append(state.gain)
    return state, gains


def test_starts_safe_and_ramps_up_without_a_jump() -> None:
    s, gains = run(WatchdogState(), 0.0, 200, got=True)
    assert gains[0] == pytest.approx(0.01)
    assert max(abs(b - a) for a, b in zip(gains, gains[1:], strict=False)) <= DT / 0.1 + 1e-12
    assert s.gain == 1.0 and not s.tripped


def test_timeout_trips_and_ramps_down() -> None:
    s, _ = run(WatchdogState(), 0.0, 200, got=True)
    s, gains = run(s, 0.2, 200, got=False)
    assert s.tripped and s.trips == 1
    # still 1 within the timeout, then a ramp of 0.1 s down to 0
    assert gains[5] == 1.0
    assert gains[50] == pytest.approx(1.0 - 41 * DT / 0.1, abs=0.011)  # +-1 tick
    assert gains[-1] == 0.0


def test_lost_liveliness_zeroes_at_once() -> None:
    s, _ = run(WatchdogState(), 0.0, 200, got=True)
    s = watchdog_step(s, P, 0.2, True, False, DT)
    assert s.gain == 0.0 and s.tripped


def test_default_timeouts_follow_period_and_delay() -> None:
    cfg = load_config(None, ["links.master_controller.delay_s=0.1",
                             "links.controller_hand.delay_s=0.05"])
    assert master_force_watchdog(cfg).timeout_s == pytest.approx(0.025 + 0.1)  # the floor
    assert hand_command_watchdog(cfg).timeout_s == pytest.approx(0.004 + 0.025 + 0.05)
    assert hand_command_watchdog(cfg).down_ramp_s == 0.0  # the hand holds at once
    cfg2 = load_config(None, ["safety.command_timeout_s=0.5"])
    assert hand_command_watchdog(cfg2).timeout_s == 0.5


@pytest.mark.slow
def test_lost_messages_at_20_percent_do_not_trip_the_master_watchdog() -> None:
    """Four lost force commands in a row at 1 kHz happen 1.6 times a second at 20 % loss; the
    master's watchdog waits ``min_timeout_s`` (25 ms: 20 in a row, ~1e-14) so lost messages
    do not ramp the force out.  The floor removed (the mutant kept): it trips."""
    loss = ["links.master_controller.loss=0.2", "links.controller_hand.loss=0.2"]
    assert run_lockstep(load_config(None, loss), 6.0, seed=1).master_watchdog_trips == 0
    bare = run_lockstep(load_config(None, [*loss, "safety.min_timeout_s=0"]), 6.0, seed=1)
    assert bare.master_watchdog_trips >= 3
