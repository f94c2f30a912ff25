"""Where a live service's samples go: a recording CSV and the rerun dashboard.

Every tick's sample is written to the recording (``--record DIR`` -> ``DIR/<role>.csv``, the
DESIGN.md format: ``t_s`` then SI-unit columns), and with a simulated port (the virtual
operator, the simulated hand) the physical work done at it so far (``audit_delivered_j``,
``audit_taken_j``: :mod:`teleop.analysis.port_audit`).  The dashboard gets the signals at
``dashboard.rate_hz`` and every event (passivity limiting, watchdog, dropped messages) as it
happens.  Time on both is seconds since the session epoch.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from services.samples import (
    ControllerSample,
    HandSample,
    MasterSample,
    Sample,
    sample_columns,
    sample_row,
)
from teleop.analysis.port_audit import AUDIT_COLUMNS
from teleop.devices.base import HandReading
from teleop.recording import RecordingWriter
from teleop.transport.safe_decoder import RejectCounts

#: words that make an event an alarm: a contact the tactile cells are not trusted on (raised
#: once per contact), cells found reading low (once: latched), or the hand's tank holding its
#: set-points back through a squeeze (once per spell); printed by a live service as well as
#: logged
ALARM_WORDS = ("yielding", "unseen contact", "cells read low", "hand starved")


def is_alarm(text: str) -> bool:
    """Whether the event ``text`` is an alarm (:data:`ALARM_WORDS`)."""
    return any(w in text for w in ALARM_WORDS)


def event_level(text: str) -> str:
    """``WARN`` for an alarm, a fault or a watchdog (logged, not printed: a fault is
    reported with every reading while it lasts, and a watchdog on a loaded host trips and
    resumes many times a second); ``INFO`` otherwise."""
    return "WARN" if is_alarm(text) or "watchdog" in text or "fault" in text else "INFO"

class Telemetry:
    """Recording and dashboard output of one service."""

    def __init__(self, role: str, rec: Any | None, record_path: Path | None,
                 epoch_s: float | None, dashboard_rate_hz: float,
                 meta: tuple[tuple[str, str], ...] = (),
                 audit_source: Callable[[], tuple[float, float]] | None = None,
                 picture_rate_hz: float = 10.0) -> None:
        self.role = role
        #: the backend's physical port audit (delivered, taken; J, cumulative), recorded with
        #: every sample when given (a simulated operator or hand: teleop.analysis.port_audit)
        self.audit_source = audit_source
        self.rec = rec
        self.record_path = record_path
        self.meta = meta
        self.epoch_s = epoch_s
        self.period_s = 1.0 / dashboard_rate_hz
        self._next_log_s = -math.inf
        # the hand's drawing and pressure bars cost ~2 ms a log in rerun's Python API (a
        # scalar ~0.08 ms): logged at their own, lower rate
        self.picture_period_s = 1.0 / picture_rate_hz
        self._next_picture_s = -math.inf
        self._writer: RecordingWriter | None = None
        self._clock_cols: list[int] = []
        self._delays: dict[str, float] = {}
        self._dropped: dict[str, float] = {}
        #: where the dashboard gets the bus's rejection counts (set by the runner)
        self.rejects_source: Callable[[], RejectCounts] | None = None
        self._rejects_logged: tuple[tuple[str, int], ...] = ()
        #: the signals, gathered and sent as columns every 0.2 s (a third of the loop's cost
        #: of logging each value at once); events and pictures go to ``rec`` at once
        self.cols: Any | None = None
        if rec is not None:  # import now, not inside the first tick
            from teleop.viz import dashboard

            self.cols = dashboard.ScalarColumns(rec)
            dashboard.warm_up()

    def _t(self, t_s: float) -> float:
        if self.epoch_s is None:
            self.epoch_s = t_s
        return t_s - self.epoch_s

    def _delay(self, key: str, value: float) -> None:
        if math.isfinite(value):
            self._delays[key] = value

    def emit(self, sample: Sample, events: list[str],
             reading: HandReading | None = None) -> None:
        """Record ``sample``; log it (at the dashboard rate) and ``events`` (always)."""
        t = self._t(sample.t_s)
        # the backend's physical work now, for the recording and the dashboard alike
        physics = self.audit_source() if self.audit_source is not None else None
        if self.record_path is not None:
            if self._writer is None:
                cols = sample_columns(sample)
                if self.audit_source is not None:
                    cols += list(AUDIT_COLUMNS)
                # clock times besides t_s (the hand's read_t_s, write_t_s): on t_s's epoch too
                self._clock_cols = [i for i, c in enumerate(cols) if c.endswith("_t_s") and i]
                self._writer = RecordingWriter(self.record_path, cols, meta=self.meta)
            row = sample_row(sample)
            row[0] = t
            if physics is not None:
                row += physics
            for i in self._clock_cols:
                row[i] -= self.epoch_s  # type: ignore[operator]
            self._writer.write(row)
        if self.rec is None:
            return
        from teleop.viz import dashboard as dash

        # achieved delays arrive on some ticks only: keep the latest from every tick
        if isinstance(sample, ControllerSample):
            self._delay("cm", sample.master_delay_s)
            self._delay("ch", sample.hand_delay_s)
        else:
            self._delay(sample.__class__.__name__, sample.delay_s)

        for text in events:
            dash.log_event(self.rec, t, self.role, text, event_level(text))
        if t < self._next_log_s:
            return
        self._next_log_s = t + self.period_s
        self._log(dash, t, sample, reading, physics)
        if self.rejects_source is not None:
            by_reason = self.rejects_source().by_reason
            if by_reason != self._rejects_logged:
                dash.log_rejects(self.cols, t, self.role, by_reason)
                self._rejects_logged = by_reason
        self.cols.flush_due(t)

    def _dropped_event(self, dash: Any, t: float, name: str, total: float) -> None:
        before = self._dropped.get(name, 0.0)
        if total > before:
            dash.log_event(self.rec, t, self.role,
                           f"dropped {total - before:.0f} {name} (total {total:.0f})", "WARN")
        self._dropped[name] = total

    def _log(self, dash: Any, t: float, s: Sample, reading: HandReading | None,
             physics: tuple[float, float] | None) -> None:
        rec = self.cols
        if isinstance(s, MasterSample):
            dash.log_master(rec, t, trigger_position_m=s.trigger_position_m,
                            displayed_force_n=s.displayed_force_n, tank_j=s.tank_j,
                            port_in_j=s.port_in_j, port_out_j=s.port_out_j,
                            delay_s=self._delays.get("MasterSample"),
                            model_force_n=s.model_force_n, physics_j=physics)
            self._dropped_event(dash, t, "force commands", s.dropped)
        elif isinstance(s, ControllerSample):
            dash.log_controller(rec, t, setpoints_rad=s.setpoint_rad,
                                commanded_force_n=s.commanded_force_n,
                                energy_stored_j=s.store_j,
                                master_delay_s=self._delays.get("cm"),
                                hand_delay_s=self._delays.get("ch"),
                                measured_force_n=s.measured_force_n)
            self._dropped_event(dash, t, "master states", s.master_dropped)
            self._dropped_event(dash, t, "hand states", s.hand_dropped)
        elif isinstance(s, HandSample) and reading is not None:
            pictures = t >= self._next_picture_s
            if pictures:
                self._next_picture_s = t + self.picture_period_s
            dash.log_hand(rec, t, reading, tank_j=s.tank_j, port_in_j=s.port_in_j,
                          port_out_j=s.port_out_j, delay_s=self._delays.get("HandSample"),
                          pictures=pictures, physics_j=physics)
            self._dropped_event(dash, t, "hand commands", s.dropped)

    def close(self) -> None:
        """Flush the recording and the dashboard stream."""
        if self._writer is not None:
            self._writer.close()
        if self.rec is not None:
            if self.cols is not None:
                self.cols.flush()
            self.rec.flush()
            self.rec.disconnect()
