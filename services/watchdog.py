"""Watchdogs: a pure per-tick step that turns "is the peer talking?" into a 0..1 gain.

``gain`` is 1 while valid messages keep coming and 0 in the safe state.  A timeout (no valid
message for ``timeout_s``) moves it towards 0 over ``down_ramp_s`` (0: at once); a vanished
liveliness token drops it to 0 at once; when messages return it rises back to 1 over
``up_ramp_s``, so the service resumes without a jump.  The services apply the gain to what
they hand their pure controller step (the master scales the received force command, the hand
blends its hold set-point into the received command, the controller scales the force it
sends), which keeps the energy accounts exact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from teleop.config import TeleopConfig
from teleop.frozen import fast_init


@dataclass(frozen=True, slots=True)
class WatchdogParams:
    """When a watchdog trips and how fast it ramps."""

    timeout_s: float
    down_ramp_s: float
    up_ramp_s: float
    enabled: bool = True


@fast_init
@dataclass(frozen=True, slots=True)
class WatchdogState:
    """Time of the last valid message, whether tripped, the gain, and trips so far."""

    last_valid_t_s: float | None = None
    tripped: bool = True
    gain: float = 0.0
    trips: int = 0


def watchdog_step(state: WatchdogState, p: WatchdogParams, t_s: float, got_valid: bool,
                  peer_alive: bool, dt_s: float) -> WatchdogState:
    """Advance the watchdog by one tick at ``t_s``."""
    if got_valid and peer_alive and state.gain >= 1.0 and not state.tripped:
        return WatchdogState(last_valid_t_s=t_s, tripped=False, gain=1.0, trips=state.trips)
    if not p.enabled:
        return WatchdogState(last_valid_t_s=t_s if got_valid else state.last_valid_t_s,
                             tripped=False, gain=1.0, trips=state.trips)
    last = t_s if got_valid else state.last_valid_t_s
    fresh = last is not None and t_s - last <= p.timeout_s
    ok = fresh and peer_alive
    gain = state.gain
    if not peer_alive:
        gain = 0.0
    elif ok:
        gain = 1.0 if p.up_ramp_s <= 0 else min(1.0, gain + dt_s / p.up_ramp_s)
    else:
        gain = 0.0 if p.down_ramp_s <= 0 else max(0.0, gain - dt_s / p.down_ramp_s)
    trips = state.trips + (1 if (not ok and not state.tripped) else 0)
    return WatchdogState(last_valid_t_s=last, tripped=not ok, gain=gain, trips=trips)


def _link_delay_s(cfg: TeleopConfig, link: str, forward: bool) -> float:
    lc = getattr(cfg.links, link)
    d = lc.delay_s if forward or lc.backward_delay_s is None else lc.backward_delay_s
    return d + 3.0 * lc.jitter_s


def _default_timeout_s(cfg: TeleopConfig, period_s: float, link: str, forward: bool) -> float:
    """An unset timeout: ``period_s`` (the sender's silence that is still normal), at least
    ``safety.min_timeout_s``, plus the link's delay and three jitters."""
    return max(period_s, cfg.safety.min_timeout_s) + _link_delay_s(cfg, link, forward)


def hand_command_watchdog(cfg: TeleopConfig, enabled: bool = True) -> WatchdogParams:
    """Hand side: no valid hand command -> hold at once; resume over ``force_ramp_s``."""
    s = cfg.safety
    timeout = s.command_timeout_s
    if timeout is None:
        timeout = _default_timeout_s(
            cfg, 4.0 / cfg.controller.rate_hz + 1.0 / cfg.hand.state_rate_hz,
            "controller_hand", True)
    return WatchdogParams(timeout, down_ramp_s=0.0, up_ramp_s=s.force_ramp_s, enabled=enabled)


def master_force_watchdog(cfg: TeleopConfig, enabled: bool = True) -> WatchdogParams:
    """Master side: no valid force command -> the force ramps to zero."""
    s = cfg.safety
    timeout = s.state_timeout_s
    if timeout is None:
        timeout = _default_timeout_s(cfg, 4.0 / cfg.controller.rate_hz,
                                     "master_controller", False)
    return WatchdogParams(timeout, down_ramp_s=s.force_ramp_s, up_ramp_s=s.force_ramp_s,
                          enabled=enabled)


def controller_state_watchdog(cfg: TeleopConfig, enabled: bool = True) -> WatchdogParams:
    """Controller: no valid hand state -> the force sent to the master ramps to zero."""
    s = cfg.safety
    timeout = s.state_timeout_s
    if timeout is None:
        timeout = _default_timeout_s(cfg, 4.0 / cfg.hand.state_rate_hz, "controller_hand",
                                     False)
    return WatchdogParams(timeout, down_ramp_s=s.force_ramp_s, up_ramp_s=s.force_ramp_s,
                          enabled=enabled)


@dataclass(frozen=True, slots=True)
class BlindHold:
    """The controller's hold on closing while it cannot see the hand.

    ``limit_rad``: per finger, the set-point the hand may not be closed past (None: no hold);
    ``until_s``: after the hand state returns, the hold stays until then (one round trip, so
    the operator feels the restored contact before the hand follows his trigger);
    ``last_rad``: the set-points sent last tick (where the hold starts).
    """

    limit_rad: tuple[float, ...] | None = None
    until_s: float = -math.inf
    last_rad: tuple[float, ...] | None = None


def blind_hold_step(s: BlindHold, blind: bool, setpoints_rad: tuple[float, ...], t_s: float,
                    round_trip_s: float) -> tuple[BlindHold, tuple[float, ...]]:
    """One controller tick: the set-points to send and the next hold.

    While ``blind`` (its hand-state watchdog tripped after the hand had been seen, the force
    to the master ramped below half: ``services.controller_service.BLIND_GAIN``), the
    set-points may open but not close past those sent when it tripped: the force to the
    master ramps out then, and an operator who feels nothing squeezes on (live, 2026-11-26: a
    hand starved of CPU for seconds, the trigger at its full 25 mm, set-points 3.0 rad sent,
    pressure 4,900 against 675 per grasp once the hand ran again).  When the hand returns the
    hold stays one ``round_trip_s`` (the master feels the contact again meanwhile), then
    releases.  Opening only: the hold takes no energy account anywhere.
    """
    limit, until = s.limit_rad, s.until_s
    if blind:
        if limit is None:
            limit = s.last_rad if s.last_rad is not None else setpoints_rad
        until = t_s + (round_trip_s if math.isfinite(round_trip_s) else 0.0)
    elif limit is not None and t_s >= until:
        limit = None
    out = (setpoints_rad if limit is None else
           tuple(min(a, b) for a, b in zip(setpoints_rad, limit, strict=True)))
    return BlindHold(limit, until, out), out
