"""The hand service: the hand's loop at the hand-state rate (40 Hz by default).

Per tick: receive hand commands -> read the hand (a simulated hand advances its physics to
``t_s``) -> the suite's pure hand step (passive set-position modulation against the hand's
tank) -> apply the limited set-points -> publish the hand state -> return a
:class:`~services.samples.HandSample`.

Watchdog: no valid command for the command timeout (or the controller's liveliness token
gone) and the hand holds at once (or opens, ``safety.hand_safe_state``): the step is handed a
hold command, so energy accounting and set-position modulation stay in force; when commands
return, the set-point blends from the hold position into the commanded one over
``safety.force_ramp_s`` (no jump).

A stale reading (the backend has no fresh measurement: a silent brain board) trips the
watchdog at once, as a vanished controller does, and that tick publishes no hand state.

Joint limits: every set-point is clamped to the hand's joint travel (fingers to
``[0, hand.dynamixel.finger_travel_rad]``, preshape to ``[0, hand.dynamixel.preshape_travel_rad]``)
twice: the received command before the step (so the energy accounts see what is applied),
and the step's output right before ``backend.apply`` (a last line of defence, counted in
``clamp_count``).  A non-finite output is never applied.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import Any

from services.samples import HandSample
from services.starve_alarm import QUIET, starve_message, starve_step
from services.suites import get_suite
from services.watchdog import WatchdogState, hand_command_watchdog, watchdog_step
from teleop.config import TeleopConfig
from teleop.control.energy_channel import EnergyLedger
from teleop.control.interface import ControllerSuite, ControlParams, control_params
from teleop.devices.base import HandBackend, HandReading
from teleop.messages import HandCommand, HandMode, HandState, Header
from teleop.transport.bus import Bus


def clamp(x: float, lo: float, hi: float) -> float:
    """``x`` limited to ``[lo, hi]``."""
    return lo if x < lo else hi if x > hi else x


def clamp_command(cmd: HandCommand, finger_max_rad: float,
                  preshape_max_rad: float) -> HandCommand:
    """``cmd`` with its set-points inside the joint limits (the same object if they are)."""
    pre = cmd.preshape_rad
    if 0.0 <= pre <= preshape_max_rad:  # inside (the comparisons clamp makes): unchanged
        for v in cmd.finger_setpoint_rad:
            if v < 0.0 or v > finger_max_rad:
                break
        else:
            return cmd
    sp = tuple(clamp(v, 0.0, finger_max_rad) for v in cmd.finger_setpoint_rad)
    pre = clamp(cmd.preshape_rad, 0.0, preshape_max_rad)
    if sp == tuple(cmd.finger_setpoint_rad) and pre == cmd.preshape_rad:
        return cmd
    return replace(cmd, finger_setpoint_rad=sp, preshape_rad=pre)  # type: ignore[type-var]


#: hand backends that report no tactile pressures (the USB hands' servo bus): the hand's
#: environment-port passivity layer would see no contact and charge nothing there
BACKENDS_WITHOUT_TACTILE = frozenset({"dynamixel"})


def hand_control_params(cfg: TeleopConfig) -> tuple[ControlParams, str]:
    """The hand side's controller parameters, and a note when the backend forces the
    servo-spring layer (``hand_port = "servo"``: no tactile bus to measure the object port)."""
    p = control_params(cfg.controller)
    if p.hand_port == "object" and cfg.hand.backend in BACKENDS_WITHOUT_TACTILE:
        return replace(p, hand_port="servo"), (
            f"hand.backend={cfg.hand.backend} has no tactile sensors: the hand's passivity "
            "layer pays the servo spring's energy (controller.ports.hand_port=servo), up to "
            "the servo's torque limit per radian a finger closes while its load-estimated "
            "contact flag is on; known to wear the grasps down within a few (README, the "
            "dynamixel backend)")
    return p, ""


class HandService:
    """The hand shell around ``suite.step_hand``."""

    role = "hand"

    def __init__(self, cfg: TeleopConfig, bus: Bus, backend: HandBackend,
                 suite: ControllerSuite | None = None, watchdogs: bool = True,
                 clock: Callable[[], float] | None = None) -> None:
        self.cfg = cfg
        self.clock = clock  # the loop's clock: when the hand was read and written (None: t_s)
        self.bus = bus
        self.backend = backend
        self.suite = suite if suite is not None else get_suite(cfg.controller.kind)
        self.params, note = hand_control_params(cfg)
        self.state: Any = self.suite.init_hand(self.params)
        self.rate_hz = cfg.hand.state_rate_hz
        self.dt_s = 1.0 / self.rate_hz
        self.seq = 0
        self.command: HandCommand | None = None
        self.command_rx_t_s: float | None = None  # when the held command arrived
        self.hold_rad: tuple[float, float, float] | None = None
        self.delay_s = math.nan
        self.dropped = 0
        self.limit_count = 0
        self._was_limited = False
        self.starve = QUIET  # the "hand starved" alarm (services.starve_alarm)
        self._starved_after_s = cfg.safety.starved_alarm_s
        self._model_fallbacks = 0
        self._yielding = 0
        self._unseen = 0
        self._cells_low = 0
        self.wd_params = hand_command_watchdog(cfg, watchdogs)
        self.wd = WatchdogState()
        self.events: list[str] = []
        self._note = note  # said once, with the first tick's events
        self.ledger: EnergyLedger | None = None  # accounts after the last tick
        self.last_reading: HandReading | None = None
        self.t0_s: float | None = None
        dx = cfg.hand.dynamixel
        self.finger_max_rad = dx.finger_travel_rad
        self.preshape_max_rad = dx.preshape_travel_rad
        self.clamp_count = 0  # received commands or outputs moved into the joint limits
        self.stale_ticks = 0  # ticks whose reading had no fresh measurement (silent hand)

    def start(self) -> None:
        """Connect and calibrate the hand."""
        self.backend.start()

    def _receive(self) -> bool:
        got = False
        for r in self.bus.receive("hand_command"):
            msg = r.message
            assert isinstance(msg, HandCommand)
            if self.command is not None and msg.header.seq > self.command.header.seq + 1:
                self.dropped += msg.header.seq - self.command.header.seq - 1
            safe = clamp_command(msg, self.finger_max_rad, self.preshape_max_rad)
            if safe is not msg:
                self.clamp_count += 1
            self.command, self.delay_s, got = safe, r.delay_s, True
        return got

    def _effective_command(self, reading: HandReading) -> HandCommand | None:
        """The command handed to the step: received, hold/open, or a blend of the two."""
        cmd = self.command
        if self.wd.gain >= 1.0 and cmd is not None:
            return cmd
        if self.cfg.safety.hand_safe_state == "open":
            safe = (self.cfg.controller.transparency.open_angle_rad,) * 3
        else:
            if self.hold_rad is None:
                self.hold_rad = tuple(f.motor_angle_rad for f in reading.fingers)  # type: ignore[assignment]
            safe = self.hold_rad
        assert safe is not None
        total = cmd.header.energy_total_j if cmd is not None else 0.0
        if cmd is None or self.wd.gain <= 0.0 or cmd.mode != HandMode.POSITION:
            sp = safe
        else:
            g = self.wd.gain
            sp = tuple(s + g * (c - s) for s, c in zip(safe, cmd.finger_setpoint_rad,
                                                       strict=True))
        header = Header(seq=cmd.header.seq if cmd else 0, t_s=cmd.header.t_s if cmd else 0.0,
                        energy_total_j=total)
        pre = cmd.preshape_rad if cmd is not None else self.cfg.controller.transparency.preshape_rad
        return HandCommand(header=header, finger_setpoint_rad=sp,  # type: ignore[arg-type]
                           preshape_rad=pre, mode=HandMode.POSITION,
                           hand_echo_t_s=cmd.hand_echo_t_s if cmd is not None else -1.0)

    def _held_s(self, t_s: float) -> float:
        """How long the held command has been held (0 before the first)."""
        return 0.0 if self.command_rx_t_s is None else max(t_s - self.command_rx_t_s, 0.0)

    def tick(self, t_s: float) -> HandSample:
        """One period at ``t_s``."""
        self.events.clear()
        if self._note:
            self.events.append(self._note)
            self._note = ""
        got = self._receive()
        if got:  # echo for the controller's round-trip measurement
            self.command_rx_t_s = t_s
        if self.t0_s is None:
            self.t0_s = t_s
        r0 = self._now(t_s)
        reading = self.backend.read(t_s - self.t0_s)  # backend time: from the first tick
        read_t_s = 0.5 * (r0 + self._now(t_s))
        self.last_reading = reading
        prev = self.wd
        # a stale reading (silent hand) trips the watchdog at once, like a vanished peer
        self.wd = watchdog_step(self.wd, self.wd_params, t_s, got,
                                self.bus.alive("controller") and not reading.stale, self.dt_s)
        if self.wd.tripped and not prev.tripped:
            self.hold_rad = None  # hold where the fingers are now
            why = "the hand reports no fresh state" if reading.stale else "no valid command"
            self.events.append(f"watchdog: {why}, hand goes to "
                               f"{self.cfg.safety.hand_safe_state}")
        elif prev.tripped and not self.wd.tripped:
            self.events.append("watchdog: commands resumed, blending back" if self.wd.trips
                               else "first command received, blending in")
        if reading.stale:
            self.stale_ticks += 1
        for fault in reading.faults:
            self.events.append(f"hand fault: {fault}")
        cmd = self._effective_command(reading)
        self.state, out = self.suite.step_hand(self.state, self.params, reading.fingers, cmd,
                                               self.dt_s, t_s)
        if self.wd.gain >= 1.0:
            self.hold_rad = None
        elif self.hold_rad is None or self.wd.tripped:
            self.hold_rad = out.setpoint_rad
        applied = HandCommand(
            header=Header(seq=self.seq, t_s=t_s, energy_total_j=out.energy_total_j),
            finger_setpoint_rad=out.setpoint_rad, preshape_rad=out.preshape_rad,
            mode=HandMode.POSITION)
        write_t_s = math.nan
        if all(math.isfinite(v) for v in (*out.setpoint_rad, out.preshape_rad)):
            limited = clamp_command(applied, self.finger_max_rad, self.preshape_max_rad)
            if limited is not applied:
                self.clamp_count += 1
                self.events.append("set-point outside the joint limits: clamped")
            w0 = self._now(t_s)
            self.backend.apply(limited)
            write_t_s = 0.5 * (w0 + self._now(t_s))
        else:
            self.events.append("non-finite set-point: not applied")
        self.seq += 1
        state_msg = HandState(
            header=Header(seq=self.seq, t_s=t_s, energy_total_j=out.energy_total_j),
            fingers=reading.fingers, preshape_rad=reading.preshape_rad,
            echo_t_s=self.command.header.t_s if self.command is not None else -1.0,
            echo_held_s=self._held_s(t_s), contact_model=out.contact_model,
            servo_fault_trips=reading.servo_fault_trips, servo_safe=reading.servo_safe)
        if not reading.stale:  # a silent hand's last state is not news: the controller's
            self.bus.publish("hand_state", state_msg)  # state watchdog ramps the force down
        if out.model_fallbacks > self._model_fallbacks:
            self.events.append("contact model: estimate diverged, dropped (the operator feels "
                               "the measured force until a new fit)")
        self._model_fallbacks = out.model_fallbacks
        if out.yielding > self._yielding:
            self.events.append(f"yielding contact: {out.yielding} finger(s) crushing or "
                               "sliding; tactile force not trusted there, further advance "
                               "charged at the servo's torque")
        self._yielding = out.yielding
        if out.unseen > self._unseen:
            self.events.append(f"unseen contact: {out.unseen} finger(s) stalled with silent "
                               "tactile cells (dead cells, or a contact off the pads); further "
                               "advance charged at the servo's torque")
        self._unseen = out.unseen
        if out.cells_low > self._cells_low:
            self.events.append(f"cells read low: {out.cells_low} finger(s) read less contact "
                               "force than the servo's load implies (tactile gain below its "
                               "margin); their work charged at the measured ratio")
        self._cells_low = out.cells_low
        if out.limited:
            if not self._was_limited:
                self.events.append("passivity layer limiting the set-points")
            self.limit_count += 1
        self._was_limited = out.limited
        self.starve, starved = starve_step(self.starve, out.limited, t_s, self._starved_after_s)
        if starved:
            cm = self.params.contact_model
            self.events.append(starve_message(t_s - self.starve.since_s,
                                              cm is None or cm.follow_held_back))
        led = self.ledger = out.ledger
        f = reading.fingers
        return HandSample(
            t_s=t_s,
            proximal_angle_rad=tuple(x.proximal_rad for x in f),  # type: ignore[arg-type]
            distal_angle_rad=tuple(x.distal_rad for x in f),  # type: ignore[arg-type]
            motor_angle_rad=tuple(x.motor_angle_rad for x in f),  # type: ignore[arg-type]
            motor_load_units=tuple(x.load_units for x in f),  # type: ignore[arg-type]
            pressure=tuple(float(p) for x in f for p in x.pressure),
            contacts=tuple(float(sum(x.contact)) for x in f),  # type: ignore[arg-type]
            preshape_rad=reading.preshape_rad, setpoint_rad=out.setpoint_rad,
            setpoint_desired_rad=out.setpoint_desired_rad, tank_j=led.tank_j,
            port_in_j=led.port_in_j, port_out_j=led.port_out_j, sent_j=led.sent_j,
            received_j=led.received_j, dissipated_j=led.dissipated_j,
            spring_energy_j=out.spring_energy_j, limited=float(out.limited),
            limit_count=float(self.limit_count), delay_s=self.delay_s if got else math.nan,
            dropped=float(self.dropped), watchdog=float(self.wd.tripped),
            model_fallbacks=float(out.model_fallbacks),
            servo_fault_trips=float(reading.servo_fault_trips),
            servo_safe=float(reading.servo_safe), yielding=float(out.yielding),
            unseen_contact=float(out.unseen), cells_low=float(out.cells_low),
            read_t_s=read_t_s, write_t_s=write_t_s)

    def _now(self, t_s: float) -> float:
        """The loop clock's time (``t_s`` without a clock: virtual time, the tick is instant)."""
        return t_s if self.clock is None else self.clock()

    def close(self) -> None:
        """Go safe and release the hand."""
        try:
            self.backend.safe(self.cfg.safety.hand_safe_state)
        finally:
            self.backend.close()

