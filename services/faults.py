"""The fault suite: named fault scenarios injected into lockstep runs, checked and measured.

Each scenario runs the three services in lockstep (:func:`services.lockstep.run_lockstep`)
with a ``hook`` that injects one fault in a window ``[start_s, end_s)`` of a grasp (the
virtual operator closes at 0.5 s over 1 s, holds 2 s, releases over 1 s), and is compared
with a fault-free baseline of the same config and seed.  Checked for every scenario:

* nothing invalid reaches a motor: every ``apply`` the hand backend receives is finite and
  inside the joint limits (a guard around the backend counts violations);
* the hand never moves on invalid data (flood: its set-point is bit-identical to the
  baseline's; controller kill and link cut: it holds still once the watchdog trips);
* passivity, judged from the physics: the physical energy audit of the lockstep run
  (``LockstepResult.audit_margin_j``: work on the simulated operator and on the object,
  from :mod:`sim.operator` / :mod:`sim.audit`, never from controller code) is >= 0 at every
  sample (energy delivered at both ports <= initial tank energy + energy taken from them);
  the controllers' own ledgers (``energy_margin_j``) are checked too, as a second column, and
  their gap to the audit is reported;
* the services recover: after the fault ends the hand's applied set-point tracks what the
  controller commands (within ``TRACK_TOL_RAD`` plus what the hand's slew limit lets it lag
  in one hand period) for ``SETTLE_S``, within ``RECOVERY_MAX_S``.  The reference is the
  loop's own command, not the fault-free run's: an operator who felt no force during an
  outage squeezes further, and a loop that follows that is working;
* nothing crashes (an exception is a failed scenario, not a crashed suite).

Usage::

    from services.faults import run_suite
    suite = run_suite(cfg, short=True)
    suite.ok, [r.recovery_s for r in suite.results]
"""

from __future__ import annotations

import math
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from services.factory import build_hand
from services.lockstep import LockstepContext, LockstepResult, run_lockstep
from services.watchdog import hand_command_watchdog
from teleop.analysis.faults import (
    energy_violations,
    held_still,
    malformed_payload,
    recovery_time_s,
)
from teleop.config import TeleopConfig
from teleop.devices.base import HandBackend, HandReading
from teleop.messages import HandCommand

#: Overrides staging the grasp every scenario runs on (one close, hold, release).
BASE_OVERRIDES: tuple[str, ...] = ("master.virtual.repeat=false",)
TRACK_TOL_RAD = 0.05
SETTLE_S = 0.25
RECOVERY_MAX_S = 1.0
DURATION_S = 5.0
FLOOD_RATE_HZ = 1000.0
SERIAL_NAME = "serial_faults"


@dataclass(frozen=True, slots=True)
class Scenario:
    """One named fault: what, when (``[start_s, end_s)``), run length, how many payloads."""

    name: str
    what: str
    start_s: float
    end_s: float
    duration_s: float = DURATION_S
    payloads: int = 0  # malformed flood: payloads per target service


def scenarios(short: bool = False) -> tuple[Scenario, ...]:
    """The suite; ``short`` shrinks the flood (CI) but keeps every scenario."""
    n_flood = 1000 if short else 10_000
    flood_end = 0.5 + n_flood / FLOOD_RATE_HZ
    return (
        Scenario("controller_restart", "kill the controller mid-grasp (hold), restart it "
                 "0.5 s later", 2.0, 2.5),
        Scenario("link_cut", "cut the controller<->hand link (both directions) for 2 s",
                 1.2, 3.2),
        Scenario("master_link_cut", "cut the master<->controller link for 2 s", 1.2, 3.2),
        Scenario("burst_loss", "50% Gilbert-Elliott burst loss (mean burst 10) on both "
                 "links for 2 s", 1.0, 3.0),
        Scenario("dup_reorder_storm", "50% duplication and 0-20 ms uniform jitter with "
                 "reordering on both links for 2 s", 1.0, 3.0),
        Scenario("malformed_flood", f"{n_flood} malformed payloads at 1 kHz into the hand's "
                 "and into the controller's inputs", 0.5, flood_end,
                 duration_s=max(DURATION_S, flood_end + 1.0), payloads=n_flood),
    )


@dataclass(frozen=True, slots=True)
class ScenarioResult:
    """Figures and verdict of one scenario."""

    name: str
    what: str
    mode: str
    ok: bool
    failures: tuple[str, ...]
    crashed: str  # "" or the exception
    fault_start_s: float
    fault_end_s: float
    injected: int  # malformed payloads put on the links
    rejected: int
    rejects_by_reason: tuple[tuple[str, int], ...]
    energy_violations: int  # samples at which the ledgers' energy balance failed
    min_energy_margin_j: float  # by the ledgers
    recovery_s: float  # inf: never recovered
    joint_limit_violations: int  # invalid set-points that reached the hand backend
    applied_commands: int
    moved_on_invalid: bool
    watchdog_trips: int
    wall_s: float
    # physical energy audit (lockstep with simulated operator and hand); "" = audited
    no_audit: str = ("none: not a lockstep run of the simulated operator and hand")  # why
    audit_violations: int = 0  # samples at which the audit margin went negative
    min_audit_margin_j: float = math.nan
    audit_energy_generated_j: float = math.nan
    ledger_audit_gap_j: tuple[tuple[str, float], ...] = ()  # per port, at the end

    @property
    def has_audit(self) -> bool:
        """Whether the verdict on passivity comes from the physical audit."""
        return not self.no_audit

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict (infinite recovery and an unmeasured margin as null).

        ``passive_audit`` is the verdict of the physical audit (null without one: live and
        serial modes run real processes or devices; ``audit`` then says why);
        ``energy_violations`` / ``min_energy_margin_j`` are the ledgers' check."""
        return {
            "name": self.name, "what": self.what, "mode": self.mode, "ok": self.ok,
            "failures": list(self.failures), "crashed": self.crashed,
            "fault_start_s": self.fault_start_s, "fault_end_s": self.fault_end_s,
            "injected": self.injected, "rejected": self.rejected,
            "rejects_by_reason": dict(self.rejects_by_reason),
            "energy_violations": self.energy_violations,
            "min_energy_margin_j": self.min_energy_margin_j
            if math.isfinite(self.min_energy_margin_j) else None,
            "recovery_s": self.recovery_s if math.isfinite(self.recovery_s) else None,
            "joint_limit_violations": self.joint_limit_violations,
            "applied_commands": self.applied_commands,
            "moved_on_invalid": self.moved_on_invalid,
            "watchdog_trips": self.watchdog_trips, "wall_s": self.wall_s,
            "audit": "physical (sim.operator, sim.audit)" if self.has_audit else self.no_audit,
            "passive_audit": (self.audit_violations == 0) if self.has_audit else None,
            "audit_violations": self.audit_violations if self.has_audit else None,
            "min_audit_margin_j": _finite_or_none(self.min_audit_margin_j),
            "audit_energy_generated_j": _finite_or_none(self.audit_energy_generated_j),
            "ledger_energy_violations": self.energy_violations,
            "ledger_audit_gap_j": {k: _finite_or_none(v) for k, v in self.ledger_audit_gap_j},
        }


def _finite_or_none(x: float) -> float | None:
    return x if math.isfinite(x) else None


@dataclass(frozen=True, slots=True)
class SuiteResult:
    """Every scenario's result."""

    mode: str
    short: bool
    seed: int
    results: tuple[ScenarioResult, ...]

    @property
    def ok(self) -> bool:
        """All scenarios passed."""
        return all(r.ok for r in self.results)

    def to_json(self) -> dict[str, Any]:
        """The ``--json`` document."""
        total: dict[str, int] = {}
        for r in self.results:
            for k, v in r.rejects_by_reason:
                total[k] = total.get(k, 0) + v
        return {"mode": self.mode, "short": self.short, "seed": self.seed, "ok": self.ok,
                "faults_run": len(self.results),
                "faults_passed": sum(r.ok for r in self.results),
                "messages_rejected": sum(r.rejected for r in self.results),
                "rejects_by_reason": dict(sorted(total.items())),
                "energy_violations": sum(r.energy_violations for r in self.results),
                "audited": sum(r.has_audit for r in self.results),
                "audit_violations": sum(r.audit_violations for r in self.results
                                        if r.has_audit),
                "scenarios": [r.to_json() for r in self.results]}


class GuardedHand:
    """A hand backend wrapper that checks every set-point before it reaches the motors."""

    def __init__(self, backend: HandBackend, finger_max_rad: float,
                 preshape_max_rad: float) -> None:
        self.backend = backend
        self.finger_max_rad = finger_max_rad
        self.preshape_max_rad = preshape_max_rad
        self.applied = 0
        self.violations = 0

    def start(self) -> None:
        """Start the wrapped backend."""
        self.backend.start()

    def apply(self, command: HandCommand) -> None:
        """Count an out-of-limit or non-finite set-point, then pass the command on."""
        self.applied += 1
        sp = (*command.finger_setpoint_rad, command.preshape_rad)
        if not all(math.isfinite(v) for v in sp) \
                or any(not -1e-9 <= v <= self.finger_max_rad + 1e-9
                       for v in command.finger_setpoint_rad) \
                or not -1e-9 <= command.preshape_rad <= self.preshape_max_rad + 1e-9:
            self.violations += 1
        self.backend.apply(command)

    def read(self, t_s: float) -> HandReading:
        """Read the wrapped backend."""
        return self.backend.read(t_s)

    def safe(self, mode: str) -> None:
        """Safe state of the wrapped backend."""
        self.backend.safe(mode)

    def close(self) -> None:
        """Close the wrapped backend."""
        self.backend.close()

    def port_audit_j(self) -> tuple[float, float]:
        """The wrapped backend's physical energy audit (nan when it has none)."""
        audit = getattr(self.backend, "port_audit_j", None)
        return audit() if audit is not None else (math.nan, math.nan)


@dataclass
class _Probe:
    """What a scenario's hook saw: every bus view (for reject counts) and the injections."""

    views: list[Any] = field(default_factory=list)
    injected: int = 0
    done: set[str] = field(default_factory=set)

    def see(self, ctx: LockstepContext) -> None:
        for svc in (ctx.master, ctx.controller, ctx.hand):
            if svc is not None and not any(v is svc.bus for v in self.views):
                self.views.append(svc.bus)

    def once(self, key: str) -> bool:
        if key in self.done:
            return False
        self.done.add(key)
        return True

    def rejects(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for v in self.views:
            for k, n in v.stats().rejects.by_reason:
                out[k] = out.get(k, 0) + n
        return out


def _link_change(link: str, **changes: Any) -> Callable[[LockstepContext, bool], None]:
    def act(ctx: LockstepContext, on: bool) -> None:
        orig = getattr(ctx.cfg.links, link)
        ctx.hub.set_link(link, replace(orig, **changes) if on else orig)
    return act


def _hook(sc: Scenario, probe: _Probe) -> Callable[[float, LockstepContext], None]:
    """The fault-injecting hook of ``sc``."""
    if sc.name == "controller_restart":
        def window(ctx: LockstepContext, on: bool) -> None:
            ctx.kill_controller() if on else ctx.restart_controller()
    elif sc.name == "link_cut":
        def window(ctx: LockstepContext, on: bool) -> None:
            ctx.hub.set_link("controller_hand", None if on else ctx.cfg.links.controller_hand)
    elif sc.name == "master_link_cut":
        def window(ctx: LockstepContext, on: bool) -> None:
            ctx.hub.set_link("master_controller",
                             None if on else ctx.cfg.links.master_controller)
    elif sc.name in ("burst_loss", "dup_reorder_storm"):
        changes: dict[str, Any] = (
            {"loss": 0.5, "loss_model": "gilbert", "burst_length": 10.0}
            if sc.name == "burst_loss" else
            {"duplicate": 0.5, "jitter": "uniform", "jitter_s": 0.02, "reorder": True})
        acts = [_link_change(k, **changes) for k in ("master_controller", "controller_hand")]

        def window(ctx: LockstepContext, on: bool) -> None:
            for a in acts:
                a(ctx, on)
    elif sc.name == "malformed_flood":
        def window(ctx: LockstepContext, on: bool) -> None:
            return None
    else:
        raise ValueError(f"unknown scenario {sc.name!r}")

    def hook(t_s: float, ctx: LockstepContext) -> None:
        probe.see(ctx)
        if t_s >= sc.start_s - 1e-12 and probe.once("start"):
            window(ctx, True)
        if t_s >= sc.end_s - 1e-12 and probe.once("end"):
            window(ctx, False)
            probe.see(ctx)
        if sc.payloads and sc.start_s - 1e-12 <= t_s < sc.end_s - 1e-12 \
                and probe.injected < 2 * sc.payloads:
            i = probe.injected // 2
            if ctx.hand is not None:
                ctx.hand.bus.inject("hand_command", malformed_payload(i, "hand_command")[1])
            if ctx.controller is not None:
                sig = "master_state" if i % 2 == 0 else "hand_state"
                ctx.controller.bus.inject(sig, malformed_payload(i, sig)[1])
            probe.injected += 2
    return hook


def _guard(cfg: TeleopConfig) -> GuardedHand:
    dx = cfg.hand.dynamixel
    return GuardedHand(build_hand(cfg), dx.finger_travel_rad, dx.preshape_travel_rad)


def run_scenario(cfg: TeleopConfig, sc: Scenario, baseline: LockstepResult,
                 seed: int = 1) -> ScenarioResult:
    """Run ``sc`` in lockstep and judge it against ``baseline`` (same cfg and seed, at least
    as long)."""
    t0 = time.perf_counter()
    probe = _Probe()
    guard = _guard(cfg)
    failures: list[str] = []
    crashed = ""
    r: LockstepResult | None = None
    try:
        r = run_lockstep(cfg, sc.duration_s, seed=seed, hand=guard, hook=_hook(sc, probe))
    except Exception as exc:  # a crash is a finding, reported per scenario
        crashed = f"{type(exc).__name__}: {exc}"
        failures.append(f"crashed: {crashed}")
        traceback.print_exc()
    rejects = probe.rejects()
    n_rej = sum(rejects.values())
    viol = guard.violations
    if viol:
        failures.append(f"{viol} set-points outside the joint limits reached the motors")
    e_viol, margin, rec, moved, trips = 0, math.nan, math.inf, False, 0
    audit: dict[str, Any] = {"no_audit": "no run"}
    if r is not None:
        n = r.t_s.size
        ref = baseline.hand_setpoint_rad[:n]
        audit = audit_figures(r)
        if audit["no_audit"]:
            failures.append(f"no physical energy audit ({audit['no_audit']})")
        elif audit["audit_violations"]:
            failures.append(f"physical energy audit: delivered exceeded initial + taken at "
                            f"{audit['audit_violations']} samples (by up to "
                            f"{audit['audit_energy_generated_j']:.4g} J)")
        e_viol = energy_violations(r.energy_margin_j)
        margin = float(np.min(r.energy_margin_j))
        trips = r.watchdog_trips
        lag = cfg.controller.ports.servo_max_speed_rad_s / cfg.hand.state_rate_hz
        rec = recovery_time_s(r.t_s, r.hand_setpoint_rad, r.setpoint_rad, sc.end_s,
                              TRACK_TOL_RAD + lag, SETTLE_S)
        if e_viol:
            failures.append(f"energy ledgers: balance violated at {e_viol} samples")
        if not rec <= RECOVERY_MAX_S:
            failures.append(f"no recovery within {RECOVERY_MAX_S} s")
        if sc.payloads:
            diff = np.nan_to_num(np.abs(r.hand_setpoint_rad - ref), nan=np.inf)
            moved = bool(np.max(diff) > 0.0)
            if moved:
                failures.append("the hand set-point moved during the malformed flood")
            if n_rej < probe.injected:
                failures.append(f"only {n_rej} of {probe.injected} payloads rejected")
        if sc.name in ("controller_restart", "link_cut"):
            hold_from = sc.start_s + hand_command_watchdog(cfg).timeout_s + 2.0 / \
                cfg.hand.state_rate_hz
            if not held_still(r.t_s, r.hand_setpoint_rad, hold_from, sc.end_s - 1e-3):
                moved = True
                failures.append("the hand moved while it had no valid command")
            if trips < 1:
                failures.append("no watchdog tripped")
        if sc.name == "dup_reorder_storm" and rejects.get("stale_seq", 0) == 0:
            failures.append("no duplicate or reordered message was rejected")
    return ScenarioResult(
        name=sc.name, what=sc.what, mode="lockstep", ok=not failures,
        failures=tuple(failures), crashed=crashed, fault_start_s=sc.start_s,
        fault_end_s=sc.end_s, injected=probe.injected, rejected=n_rej,
        rejects_by_reason=tuple(sorted(rejects.items())), energy_violations=e_viol,
        min_energy_margin_j=margin, recovery_s=rec, joint_limit_violations=viol,
        applied_commands=guard.applied, moved_on_invalid=moved, watchdog_trips=trips,
        wall_s=time.perf_counter() - t0, **audit)


def audit_figures(r: LockstepResult) -> dict[str, Any]:
    """The physical-audit fields of a :class:`ScenarioResult` for lockstep run ``r``."""
    if not r.has_audit:
        return {"no_audit": "a backend reported no physical audit (not simulated)"}
    m = r.audit_margin_j
    gap = r.ledger_audit_gap_j
    return {"no_audit": "", "audit_violations": energy_violations(m),
            "min_audit_margin_j": float(np.min(m)) if m.size else math.nan,
            "audit_energy_generated_j": r.audit_energy_generated_j,
            "ledger_audit_gap_j": tuple(sorted(gap.items()))}


def run_suite(cfg: TeleopConfig, *, short: bool = False, seed: int = 1,
              names: tuple[str, ...] | None = None, serial: bool = True,
              progress: Callable[[ScenarioResult], None] | None = None) -> SuiteResult:
    """Run the scenarios (all, or those in ``names``) in lockstep on ``cfg``, then (with
    ``serial``) the real-time serial-fault scenario (:mod:`services.faults_serial`).

    ``cfg`` should stage a single grasp (see :data:`BASE_OVERRIDES`).
    """
    chosen = [s for s in scenarios(short) if names is None or s.name in names]
    if names is not None:
        unknown = set(names) - set(scenario_names())
        if unknown:
            raise ValueError(f"unknown scenario(s): {', '.join(sorted(unknown))}")
    results = []
    if chosen:
        longest = max(s.duration_s for s in chosen)
        baseline = run_lockstep(cfg, longest, seed=seed, hand=_guard(cfg))
        for sc in chosen:
            res = run_scenario(cfg, sc, baseline, seed)
            results.append(res)
            if progress is not None:
                progress(res)
    if serial and (names is None or SERIAL_NAME in names):
        from services.faults_serial import run_serial_scenario

        res = run_serial_scenario(cfg, seed=seed)
        results.append(res)
        if progress is not None:
            progress(res)
    return SuiteResult("lockstep", short, seed, tuple(results))


def scenario_names() -> tuple[str, ...]:
    """Every scenario name ``run_suite`` knows (lockstep ones, then the serial one)."""
    return (*(s.name for s in scenarios(True)), SERIAL_NAME)


__all__ = ["BASE_OVERRIDES", "GuardedHand", "Scenario", "ScenarioResult", "SuiteResult",
           "audit_figures", "run_scenario", "run_suite", "scenario_names", "scenarios"]
