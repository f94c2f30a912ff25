"""The master service: the grasp trigger's loop (1 kHz by default).

Per tick: receive force commands -> read the trigger -> the controller suite's pure master
step (passivity layer, tank level controller) -> display the force -> publish the master state
-> return a :class:`~services.samples.MasterSample` (recorded and logged by the caller).

Watchdog: no valid force command for the state timeout and the force ramps to zero (the
received command is scaled before the step, so the energy accounts stay exact); the
controller's liveliness token vanishing zeroes it at once; it ramps back when commands return.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

from services.samples import MasterSample
from services.suites import get_suite
from services.watchdog import WatchdogState, master_force_watchdog, watchdog_step
from teleop.config import TeleopConfig
from teleop.control.energy_channel import EnergyLedger
from teleop.control.interface import ControllerSuite, control_params, master_message
from teleop.devices.base import MasterBackend
from teleop.messages import ForceCommand, scaled_model
from teleop.transport.bus import Bus


class MasterService:
    """The master shell around ``suite.step_master``."""

    role = "master"

    def __init__(self, cfg: TeleopConfig, bus: Bus, backend: MasterBackend,
                 suite: ControllerSuite | None = None, watchdogs: bool = True) -> None:
        self.cfg = cfg
        self.bus = bus
        self.backend = backend
        self.suite = suite if suite is not None else get_suite(cfg.controller.kind)
        self.params = control_params(cfg.controller)
        self.state: Any = self.suite.init_master(self.params)
        self.rate_hz = cfg.master.rate_hz
        self.dt_s = 1.0 / self.rate_hz
        self.seq = 0
        self.command: ForceCommand | None = None
        self.command_rx_t_s: float | None = None  # when the held command arrived
        self.delay_s = math.nan
        self.dropped = 0
        self.limit_count = 0
        self._was_limited = False
        self.wd_params = master_force_watchdog(cfg, watchdogs)
        self.wd = WatchdogState()
        self.events: list[str] = []
        self.ledger: EnergyLedger | None = None  # accounts after the last tick
        self._prev_t_s: float | None = None

    def start(self) -> None:
        """Start the device."""
        self.backend.start()

    def _receive(self) -> bool:
        got = False
        for r in self.bus.receive("force_command"):
            msg = r.message
            assert isinstance(msg, ForceCommand)
            if self.command is not None and msg.header.seq > self.command.header.seq + 1:
                self.dropped += msg.header.seq - self.command.header.seq - 1
            self.command = msg
            self.delay_s = r.delay_s
            got = True
        return got

    def _elapsed_s(self, t_s: float) -> float:
        """The time since the last tick in whole periods: one period normally, more after the
        loop dropped deadlines in a stall, so the layer's velocity (position step over this
        time) does not read a 30 ms stall's motion as 30x the speed, and a damping jolt."""
        prev, self._prev_t_s = self._prev_t_s, t_s
        if prev is None:
            return self.dt_s
        return max(round((t_s - prev) / self.dt_s), 1) * self.dt_s

    def tick(self, t_s: float) -> MasterSample:
        """One period at ``t_s``."""
        self.events.clear()
        got = self._receive()
        prev = self.wd
        self.wd = watchdog_step(self.wd, self.wd_params, t_s, got,
                                self.bus.alive("controller"), self.dt_s)
        if self.wd.tripped != prev.tripped and self.wd.trips:
            self.events.append("watchdog: no force command, force ramps to zero"
                               if self.wd.tripped else "watchdog: force commands resumed")
        cmd = self.command
        if cmd is not None and self.wd.gain < 1.0:
            g = self.wd.gain  # the rendered contact model ramps out with the force
            cmd = replace(cmd, force_n=cmd.force_n * g,
                          model=scaled_model(cmd.model, g))
        reading = self.backend.read(t_s)
        self.state, out = self.suite.step_master(self.state, self.params,
                                                 reading.grip_position_m, cmd,
                                                 self._elapsed_s(t_s))
        self.backend.apply_force(out.force_n)
        self.seq += 1
        if got:  # echo for the controller's round-trip measurement
            self.command_rx_t_s = t_s
        echo = self.command.header.t_s if self.command is not None else -1.0
        held = 0.0 if self.command_rx_t_s is None else max(t_s - self.command_rx_t_s, 0.0)
        self.bus.publish("master_state", master_message(out, self.seq, t_s, echo, held))
        if out.limited:
            if not self._was_limited:
                self.events.append(f"passivity layer limiting the force "
                                   f"({out.force_desired_n:.2f} -> {out.force_n:.2f} N)")
            self.limit_count += 1
        self._was_limited = out.limited
        op_force = getattr(self.backend, "operator_force_n", None)
        led = self.ledger = out.ledger
        return MasterSample(
            t_s=t_s, trigger_position_m=reading.grip_position_m,
            trigger_velocity_m_s=reading.grip_velocity_m_s, displayed_force_n=out.force_n,
            force_desired_n=out.force_desired_n,
            force_command_n=self.command.force_n if self.command is not None else math.nan,
            operator_force_n=op_force() if callable(op_force) else math.nan,
            tank_j=led.tank_j, port_in_j=led.port_in_j, port_out_j=led.port_out_j,
            sent_j=led.sent_j, received_j=led.received_j, dissipated_j=led.dissipated_j,
            tlc_damping_n_s_per_m=out.tlc_damping_n_s_per_m, limited=float(out.limited),
            limit_count=float(self.limit_count), delay_s=self.delay_s if got else math.nan,
            dropped=float(self.dropped), watchdog=float(self.wd.tripped),
            model_force_n=out.model_force_n, model_phase=out.model_phase)

    def close(self) -> None:
        """Force off and release the device."""
        try:
            self.backend.apply_force(0.0)
        finally:
            self.backend.close()
