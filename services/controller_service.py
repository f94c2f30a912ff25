"""The controller service (the NUC): transparency layer and energy forwarding (1 kHz).

Per tick: receive master states and hand states -> the suite's pure controller step with the
latest of each -> publish the force command and the hand command -> return a
:class:`~services.samples.ControllerSample`.

Watchdog: no valid hand state for the state timeout and the force sent to the master ramps to
zero; the hand's liveliness token vanishing zeroes it at once.  Once it has been tripped long
enough for the force sent to ramp below half (after the hand had been seen), the set-points
sent may open but not close past those of then, until one round trip after the hand returns
(:func:`services.watchdog.blind_hold_step`).
(The controller has no physical port, so scaling the force it sends changes no energy
account; the master's passivity layer still governs what is displayed.)
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

from services.samples import ControllerSample
from services.suites import get_suite
from services.watchdog import (
    BlindHold,
    WatchdogState,
    blind_hold_step,
    controller_state_watchdog,
    watchdog_step,
)
from teleop.config import TeleopConfig
from teleop.control.energy_channel import EnergyLedger
from teleop.control.interface import ControllerSuite, control_params
from teleop.control.transparency_layer import combined_force_n
from teleop.messages import HandMode, HandState, MasterState, scaled_model
from teleop.transport.bus import Bus

#: the blind hold starts once the force sent has ramped below this share: the operator has
#: lost half of what he felt.  A brief trip (four hand states lost at 20 % loss, up to 75 ms
#: of a 0.2 s ramp) leaves him most of it; holding then, for the trip and a round trip, cost
#: a grasp at 1 s in lockstep (0.47 of the first over 10 minutes)
BLIND_GAIN = 0.5
#: hand modes whose set-points are joint angles (the blind hold applies to them)
_ANGLE_MODES = (HandMode.POSITION, HandMode.VELOCITY)


class ControllerService:
    """The controller shell around ``suite.step_controller``."""

    role = "controller"

    def __init__(self, cfg: TeleopConfig, bus: Bus, suite: ControllerSuite | None = None,
                 watchdogs: bool = True) -> None:
        self.cfg = cfg
        self.bus = bus
        self.suite = suite if suite is not None else get_suite(cfg.controller.kind)
        self.params = control_params(cfg.controller)
        self.state: Any = self.suite.init_controller(self.params)
        self.rate_hz = cfg.controller.rate_hz
        self.dt_s = 1.0 / self.rate_hz
        self.master: MasterState | None = None
        self.hand: HandState | None = None
        self.master_dropped = 0
        self.hand_dropped = 0
        self.wd_params = controller_state_watchdog(cfg, watchdogs)
        self.wd = WatchdogState()
        self.blind = BlindHold()
        self.events: list[str] = []
        self.ledger: EnergyLedger | None = None  # accounts after the last tick

    def start(self) -> None:
        """Nothing to connect."""

    def tick(self, t_s: float) -> ControllerSample:
        """One period at ``t_s``."""
        self.events.clear()
        m_delay = h_delay = math.nan
        for r in self.bus.receive("master_state"):
            msg = r.message
            assert isinstance(msg, MasterState)
            if self.master is not None and msg.header.seq > self.master.header.seq + 1:
                self.master_dropped += msg.header.seq - self.master.header.seq - 1
            self.master, m_delay = msg, r.delay_s
        got_hand = False
        for r in self.bus.receive("hand_state"):
            msg = r.message
            assert isinstance(msg, HandState)
            if self.hand is not None and msg.header.seq > self.hand.header.seq + 1:
                self.hand_dropped += msg.header.seq - self.hand.header.seq - 1
            if msg.servo_safe and not (self.hand is not None and self.hand.servo_safe):
                self.events.append(f"hand: servo error bits, the hand holds its safe state "
                                   f"(episode {msg.servo_fault_trips})")
            self.hand, h_delay, got_hand = msg, r.delay_s, True
        prev = self.wd
        self.wd = watchdog_step(self.wd, self.wd_params, t_s, got_hand, self.bus.alive("hand"),
                                self.dt_s)
        if self.wd.tripped != prev.tripped and self.wd.trips:
            self.events.append("watchdog: no hand state, force to the master ramps to zero"
                               if self.wd.tripped else "watchdog: hand state resumed")
        self.state, out = self.suite.step_controller(self.state, self.params, self.master,
                                                     self.hand, t_s, self.dt_s)
        fc = out.force_command
        if self.wd.gain < 1.0:  # the contact model is as stale as the force: both ramp out
            g = self.wd.gain
            fc = replace(fc, force_n=fc.force_n * g,
                         model=scaled_model(fc.model, g))
        hc = out.hand_command
        # blind (the hand seen before, its state now stale): no closing past the set-points
        # of the trip until the master has felt the contact again (services.watchdog)
        rt = out.round_trip_s
        if not math.isfinite(rt):
            rt = 2.0 * self.cfg.links.master_controller.delay_s
        blind = (self.wd.tripped and self.wd.trips > 0 and self.wd.gain < BLIND_GAIN
                 and hc.mode in _ANGLE_MODES)
        wanted = tuple(hc.finger_setpoint_rad)
        self.blind, sp = blind_hold_step(self.blind, blind, wanted, t_s, rt)
        if sp != wanted:
            hc = replace(hc, finger_setpoint_rad=sp)
        self.bus.publish("force_command", fc)
        self.bus.publish("hand_command", hc)
        led = self.ledger = out.ledger
        return ControllerSample(
            t_s=t_s, setpoint_rad=tuple(hc.finger_setpoint_rad),  # type: ignore[arg-type]
            preshape_rad=hc.preshape_rad, commanded_force_n=fc.force_n,
            force_desired_n=out.force_desired_n,
            max_pressure=tuple(out.max_pressure),  # type: ignore[arg-type]
            store_j=led.tank_j, sent_j=led.sent_j, received_j=led.received_j,
            dissipated_j=led.dissipated_j, master_delay_s=m_delay, hand_delay_s=h_delay,
            master_dropped=float(self.master_dropped), hand_dropped=float(self.hand_dropped),
            watchdog=float(self.wd.tripped), force_gain=out.force_gain,
            round_trip_s=out.round_trip_s,
            measured_force_n=combined_force_n(out.max_pressure, self.params),
            hand_servo_fault_trips=float(self.hand.servo_fault_trips) if self.hand else 0.0)

    def close(self) -> None:
        """Nothing to release."""
