"""The serial-fault scenario: the hand service on the dynamixel backend, through the real
dynamixel-sdk, against emulated MX-28s on a pseudo-terminal that drop replies and corrupt
checksums for a while.

Unlike the lockstep scenarios this one runs in real time (the emulator is a thread serving a
pty), with a scripted controller view that closes the fingers to 1 rad and holds.  Checked:
no crash, nothing outside the joint limits reaches the servos, the backend's retries absorb
the faults (the hand does not latch safe), the reported finger angles never jump (a corrupt
reply is never taken for a position), the hand's energy ledger balances with a non-negative
tank, and after the faults end the fingers track the set-point again (recovery time).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import replace

import numpy as np

from services.faults import GuardedHand, ScenarioResult
from services.hand_service import HandService
from teleop.analysis.faults import recovery_time_s
from teleop.config import TeleopConfig
from teleop.control.energy_channel import ledger_residual_j
from teleop.messages import HandCommand, HandMode, Header
from teleop.transport.clock import VirtualClock
from teleop.transport.inproc_bus import InProcessHub

NAME = "serial_faults"
CLOSE_RAD = 1.0
TRACK_TOL_RAD = 0.08
#: Largest plausible change of a reported finger angle: a margin plus the fastest joint
#: motion times the wall time between the two reads (a late tick on a busy machine is fine).
STEP_MARGIN_RAD = 0.15
MAX_JOINT_SPEED_RAD_S = 8.0


def _reason(fault: str) -> str:
    f = fault.lower()
    if "no status" in f or "timeout" in f or "timed out" in f:
        return "serial_no_reply"
    if "incorrect status" in f or "checksum" in f or "crc" in f or "corrupt" in f:
        return "serial_corrupt"
    if "safe" in f:
        return "serial_safe_state"
    return "serial_other"


class _FailureCounter(logging.Handler):
    """Counts the backend's logged bus-transaction failures (each retry attempt) by reason."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.counts: dict[str, int] = {}

    def emit(self, record: logging.LogRecord) -> None:
        msg = record.getMessage()
        if "failed" in msg:
            r = _reason(msg)
            self.counts[r] = self.counts.get(r, 0) + 1


def run_serial_scenario(cfg: TeleopConfig, *, duration_s: float = 3.5,
                        window_s: tuple[float, float] = (1.0, 2.5), drop_rate: float = 0.1,
                        corrupt_rate: float = 0.05, seed: int = 1) -> ScenarioResult:
    """Run the serial-fault scenario and judge it (see the module docstring)."""
    from sim.servo_emulator_bus import FaultConfig
    from sim.servo_emulator_pty import PtyServoEmulator, make_bus_emulator
    from teleop.devices.dynamixel_hand import build_dynamixel_hand

    t_wall = time.perf_counter()
    what = (f"dynamixel bus: {drop_rate:.0%} dropped replies and {corrupt_rate:.0%} corrupt "
            f"checksums for {window_s[1] - window_s[0]:g} s (real time, pty emulator)")
    failures: list[str] = []
    crashed = ""
    reported = 0  # faults the backend reported to the service (after its retries)
    emu = PtyServoEmulator(make_bus_emulator(1, physics="simple"))
    emu.start()
    dx = replace(cfg.hand.dynamixel, port=emu.path, protocol=1.0, timeout_s=0.05, retries=2,
                 zeros_rad=(0.0, 0.0, 0.0, 0.0), overload_finger_units=1023.0)
    hcfg = replace(cfg.hand, backend="dynamixel", dynamixel=dx)
    run_cfg = replace(cfg, hand=hcfg)
    guard = GuardedHand(build_dynamixel_hand(hcfg), dx.finger_travel_rad, dx.preshape_travel_rad)
    clock = VirtualClock(0.0)
    hub = InProcessHub.from_config(run_cfg, clock)
    svc = HandService(run_cfg, hub.bus("hand"), guard)
    ctrl = hub.bus("controller")
    rate = run_cfg.hand.state_rate_hz
    ts: list[float] = []
    walls: list[float] = []
    sp: list[tuple[float, ...]] = []
    angle: list[tuple[float, ...]] = []
    ledger_bad = 0
    latched = ""
    log = logging.getLogger("teleop.devices.dynamixel")
    counter = _FailureCounter()
    log.addHandler(counter)
    propagate, log.propagate = log.propagate, False  # counted, not printed
    try:
        svc.start()
        t0 = time.monotonic()
        k = 0
        faults_on = faults_off = False
        while (t := k / rate) <= duration_s:
            wait = t0 + t - time.monotonic()
            if wait > 0:
                time.sleep(wait)
            if t >= window_s[0] and not faults_on:
                emu.bus.faults = FaultConfig(drop_rate=drop_rate, corrupt_rate=corrupt_rate,
                                             seed=seed)
                faults_on = True
            if t >= window_s[1] and not faults_off:
                emu.bus.faults = FaultConfig()
                faults_off = True
            clock.set(t)
            target = CLOSE_RAD * min(1.0, t / window_s[0])
            ctrl.publish("hand_command", HandCommand(Header(k + 1, t, 0.02 * (k + 1)),
                                                     (target,) * 3, 0.0, HandMode.POSITION))
            s = svc.tick(t)
            reported += sum(ev.startswith("hand fault: ") for ev in svc.events)
            led = svc.ledger
            if led is not None and (led.tank_j < -1e-9 or abs(ledger_residual_j(led)) > 1e-6):
                ledger_bad += 1
            ts.append(t)
            walls.append(time.monotonic())
            sp.append(s.setpoint_rad)
            angle.append(s.motor_angle_rad)
            k += 1
        latched = getattr(guard.backend, "safe_reason", "")
    except Exception as exc:  # a crash is a finding
        crashed = f"{type(exc).__name__}: {exc}"
        failures.append(f"crashed: {crashed}")
    finally:
        try:
            svc.close()
        finally:
            ctrl.close()
            injected = emu.bus.counters.dropped + emu.bus.counters.corrupted
            emu.stop()
            log.removeHandler(counter)
            log.propagate = propagate
    reasons = dict(counter.counts)
    if reported:
        reasons["serial_fault_reported"] = reported
    rec = math.inf
    if ts:
        t_a, sp_a, ang_a = np.array(ts), np.array(sp), np.array(angle)
        rec = recovery_time_s(t_a, ang_a, sp_a, window_s[1], TRACK_TOL_RAD, 0.25)
        steps = np.abs(np.diff(ang_a, axis=0))
        allowed = STEP_MARGIN_RAD + MAX_JOINT_SPEED_RAD_S * np.diff(np.array(walls))
        if steps.size and np.any(~(steps <= allowed[:, None])):
            failures.append(f"a finger angle jumped by {float(np.nanmax(steps)):.3f} rad")
        if not rec <= 1.0:
            failures.append("the fingers did not track the set-point again within 1 s")
    if latched:
        failures.append(f"the hand latched safe: {latched}")
    if guard.violations:
        failures.append(f"{guard.violations} set-points outside the joint limits reached "
                        "the servos")
    if ledger_bad:
        failures.append(f"hand energy ledger off at {ledger_bad} ticks")
    if not reasons and not crashed:
        failures.append("no serial fault was seen (injection did not work)")
    return ScenarioResult(
        name=NAME, what=what, mode="realtime", ok=not failures, failures=tuple(failures),
        crashed=crashed, fault_start_s=window_s[0], fault_end_s=window_s[1], injected=injected,
        rejected=sum(v for k, v in reasons.items() if k != "serial_fault_reported"),
        rejects_by_reason=tuple(sorted(reasons.items())),
        energy_violations=ledger_bad, min_energy_margin_j=math.nan, recovery_s=rec,
        joint_limit_violations=guard.violations, applied_commands=guard.applied,
        moved_on_invalid=False, watchdog_trips=svc.wd.trips, wall_s=time.perf_counter() - t_wall)


__all__ = ["NAME", "run_serial_scenario"]
