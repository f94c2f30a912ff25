"""Config sections for safety, dashboards, recordings and the delay sweep."""

from __future__ import annotations

from dataclasses import dataclass

from teleop.config.loader import param


@dataclass(frozen=True, slots=True)
class SafetyConfig:
    """Watchdogs, safe states and message validation limits."""

    command_timeout_s: float | None = param(
        None, "no valid command for this long and the hand goes safe (unset: 4x the command "
        "period plus the configured delay)", unit="s", lo=0.0, hi=60.0)
    state_timeout_s: float | None = param(
        None, "no valid hand state for this long and the master force ramps to zero (unset: "
        "4x the state period plus the configured delay)", unit="s", lo=0.0, hi=60.0)
    min_timeout_s: float = param(0.025, "shortest silence a watchdog with an unset timeout "
                                 "waits before it trips (plus the link's delay): four periods "
                                 "at 1 kHz (4 ms) trip on four lost messages in a row, 1.6 "
                                 "times a second at 20 % loss, and on the 5-40 ms stalls of a "
                                 "loaded machine", unit="s", lo=0.0, hi=60.0)
    hand_safe_state: str = param("hold", "what the hand does when commands stop",
                                 choices=("hold", "open"))
    force_ramp_s: float = param(0.2, "time the master force takes to ramp to zero", unit="s",
                                lo=0.0, hi=10.0)
    starved_alarm_s: float = param(1.5, "the hand's tank holding its set-points back this long "
                                   "in one spell raises the 'hand starved' alarm (a healthy "
                                   "grasp: ~1 s at most, the first one live; a starved hand: "
                                   "every squeeze, 2-3.4 s; 0: off)", unit="s", lo=0.0, hi=60.0)
    energy_jump_max_j: float = param(10.0, "largest accepted increase of a peer's cumulative "
                                     "energy total in one message", unit="J", lo=0.0, hi=1e6)
    seq_jump_max: int = param(10_000, "largest accepted advance of a peer's sequence number over "
                              "the last accepted one; a message further ahead is dropped as "
                              "seq_jump and does not move the sequence filter (a restarted "
                              "peer is accepted from its first seq through its new epoch)",
                              unit="messages", lo=1, hi=10**12)


@dataclass(frozen=True, slots=True)
class DashboardConfig:
    """Live rerun dashboard."""

    mode: str = param("auto", "spawn a viewer, serve a web viewer, save to a file, or off "
                      "(auto: spawn with a display, else save)",
                      choices=("auto", "spawn", "web", "save", "off"))
    path: str = param("teleop.rrd", "file written in save mode")
    rate_hz: float = param(50.0, "rate at which services log to the dashboard", unit="Hz",
                           lo=1.0, hi=1000.0)
    picture_rate_hz: float = param(
        10.0, "rate at which the hand logs its drawing and pressure bars (about 2 ms of the "
        "hand's loop each; its signals go at rate_hz)", unit="Hz", lo=0.1, hi=1000.0)


@dataclass(frozen=True, slots=True)
class SweepConfig:
    """The delay-sweep stability test."""

    delays_s: tuple[float, ...] = param(
        (0.0, 0.01, 0.02, 0.05, 0.1, 0.2, 0.3, 0.5, 0.75, 1.0),
        "one-way master<->controller delays", unit="s", lo=0.0, hi=10.0)
    losses: tuple[float, ...] = param((0.0, 0.2), "loss probabilities", lo=0.0, hi=1.0)
    jitter_s: float = param(0.0, "jitter scale applied at every point", unit="s", lo=0.0)
    controllers: tuple[str, ...] = param(("two-layer", "direct", "tdpa"), "controllers swept",
                                         choices=("two-layer", "direct", "tdpa"))
    duration_s: float = param(6.0, "simulated time per run", unit="s", lo=0.1, hi=3600.0)
    scenario: tuple[str, ...] = param(
        ("master.virtual.closed_fraction=0.6", "master.virtual.repeat=false",
         "master.virtual.hold_s=100.0"),
        "config overrides (key=value, applied before --set) that stage the sweep's grasp: one "
        "close onto the object, then a hold whose contact force stays below the trigger's "
        "force limit, so the loop is in its linear range where delay can destabilise it")
    workers: int = param(0, "lockstep runs in parallel (spawned processes; 0 = one per core)",
                         lo=0, hi=64)
    refine_steps: int = param(5, "bisection runs narrowing each controller's largest stable "
                              "delay at zero loss", lo=0, hi=20)
