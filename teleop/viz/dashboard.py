"""The live rerun dashboard: entity paths, blueprint, and log functions per service.

Every function takes an explicit :class:`rerun.RecordingStream`; nothing global.  The three
services log into one recording (same application and recording id) under::

    master/trigger_position_m        master/displayed_force_n     master/tank_j
    master/model_force_n             controller/measured_force_n  (felt, rendered, true force)
    master/port_in_j, port_out_j     controller/setpoint_rad/f{1,2,3}
    master/physics_{delivered,taken}_j, hand/physics_{delivered,taken}_j (simulated ports)
    controller/commanded_force_n     controller/energy_stored_j   hand/finger{1,2,3}/proximal_rad
    hand/finger{1,2,3}/distal_rad    hand/tank_j                  hand/port_in_j, port_out_j
    links/<link>/delay_s             hand/pressure (27 bars)      hand/drawing/*
    events (text log: passivity limiting, watchdogs, dropped messages)
    rejects/<role>/<reason>          (messages each service's bus rejected, cumulative)

Time is the ``time`` timeline (a duration: seconds since the session's epoch).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import rerun as rr
import rerun.blueprint as rrb

from teleop.devices.base import HandReading
from teleop.errors import UserInputError

APPLICATION_ID = "teleop"
TIMELINE = "time"

LINKS: tuple[str, ...] = ("master_to_controller", "controller_to_master",
                          "controller_to_hand", "hand_to_controller")

#: every path the dashboard shows data at (the end-to-end test checks each one holds data)
DASHBOARD_PATHS: tuple[str, ...] = (
    "master/trigger_position_m", "master/displayed_force_n", "master/tank_j",
    "master/port_in_j", "master/port_out_j",
    *(f"controller/setpoint_rad/f{i}" for i in (1, 2, 3)),
    "controller/commanded_force_n", "controller/energy_stored_j",
    "master/model_force_n", "controller/measured_force_n",
    *(f"hand/finger{i}/{j}" for i in (1, 2, 3) for j in ("proximal_rad", "distal_rad")),
    "hand/tank_j", "hand/port_in_j", "hand/port_out_j",
    *(f"links/{link}/delay_s" for link in LINKS),
    "hand/pressure", "hand/drawing/links", "hand/drawing/tendon", "hand/drawing/sensors",
    "events",
)

#: the physical work at each simulated port (the virtual operator, the simulated hand), beside
#: the controllers' books: data only where the port is simulated
PHYSICS_PATHS: tuple[str, ...] = tuple(f"{side}/physics_{k}_j" for side in ("master", "hand")
                                       for k in ("delivered", "taken"))

# ReFlex finger geometry for drawing (m): proximal axle -> distal joint, distal link length,
# tactile sensor positions along each link (reference/reflex-hardware.md)
_PROXIMAL_M = 0.072
_DISTAL_M = 0.045
_PROX_SENSORS_M = (0.0189, 0.0268, 0.0347, 0.0427, 0.0506)
_DIST_SENSORS_M = (0.0114, 0.0193, 0.0272, 0.0375)
_FINGER_SPACING_M = 0.14
_TENDON_OFFSET_M = 0.006


def blueprint() -> rrb.Blueprint:
    """The dashboard layout."""
    fingers = [f"+ hand/finger{i}/**" for i in (1, 2, 3)]
    return rrb.Blueprint(
        rrb.Grid(
            rrb.TimeSeriesView(name="trigger position vs finger angles",
                               contents=["+ master/trigger_position_m", *fingers,
                                         "+ controller/setpoint_rad/**"]),
            rrb.TimeSeriesView(name="felt vs true force (rendered model, delayed command)",
                               contents=["+ master/displayed_force_n",
                                         "+ controller/measured_force_n",
                                         "+ master/model_force_n",
                                         "+ controller/commanded_force_n"]),
            rrb.TimeSeriesView(name="tanks and energy flows",
                               contents=["+ master/tank_j", "+ hand/tank_j",
                                         "+ master/port_in_j", "+ master/port_out_j",
                                         "+ hand/port_in_j", "+ hand/port_out_j",
                                         *(f"+ {p}" for p in PHYSICS_PATHS),
                                         "+ controller/energy_stored_j"]),
            rrb.TimeSeriesView(name="achieved delay per link", origin="links"),
            rrb.BarChartView(name="pressure sensors (27)", origin="hand/pressure"),
            rrb.Spatial2DView(name="fingers", origin="hand/drawing"),
            rrb.TextLogView(name="events", origin="events"),
            rrb.TimeSeriesView(name="rejected messages per reason", origin="rejects"),
        ),
        collapse_panels=True,
    )


def open_stream(recording_id: str, mode: str, path: str | Path | None = None,
                url: str | None = None, send_blueprint: bool = True) -> rr.RecordingStream | None:
    """A recording stream for one process: ``save`` to ``path``, ``connect`` to a viewer at
    ``url``, ``spawn`` a viewer, serve a ``web`` viewer, or ``off`` (None)."""
    if mode == "off":
        return None
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id, send_properties=False)
    bp = blueprint() if send_blueprint else None
    if mode == "save":
        if path is None:
            raise ValueError("save mode needs a path")
        try:
            Path(path).parent.mkdir(parents=True, exist_ok=True)
            rec.save(str(path), default_blueprint=bp)
        except (RuntimeError, OSError) as exc:
            raise UserInputError(f"{path}: cannot write the dashboard recording ({exc})") \
                from None
    elif mode == "connect":
        rec.connect_grpc(url, default_blueprint=bp)
    elif mode == "spawn":
        rec.spawn(default_blueprint=bp)
    elif mode == "web":
        uri = rec.serve_grpc(default_blueprint=bp)
        rr.serve_web_viewer(connect_to=uri, open_browser=False)
    else:
        raise ValueError(f"unknown dashboard mode {mode!r}")
    return rec


class ScalarColumns:
    """A recording stream whose scalars are gathered per entity path and sent as one column
    each, every path at most every ``flush_s``; pictures and text go straight to ``rec``.
    rerun's Python ``log`` costs ~0.08 ms a scalar; ``send_columns`` of ten samples ~0.24 ms,
    so a service's loop pays a third for its signals, and the viewer sees them up to
    ``flush_s`` late.  A round of sends is spread over the calls of :meth:`flush_due`,
    ``per_call`` columns each, so no one tick of a 1 kHz loop pays for all of them (the
    master's eight columns at once took ~2 ms).  Pass it wherever a log function takes a
    stream."""

    def __init__(self, rec: rr.RecordingStream, flush_s: float = 0.2,
                 per_call: int = 2) -> None:
        self.rec = rec
        self.flush_s = flush_s
        self.per_call = per_call
        self.t_s = 0.0
        self._cols: dict[str, tuple[list[float], list[float]]] = {}
        self._next_flush_s = -math.inf
        self._pending: list[str] = []  # paths of the present round not yet sent

    def add(self, path: str, value: float) -> None:
        """``value`` at ``path`` at the present time (:func:`set_time`)."""
        col = self._cols.get(path)
        if col is None:
            col = self._cols[path] = ([], [])
        col[0].append(self.t_s)
        col[1].append(value)

    def _send(self, path: str) -> None:
        ts, vs = self._cols[path]
        if ts:
            rr.send_columns(path, indexes=[rr.TimeColumn(TIMELINE, duration=ts)],
                            columns=rr.Scalars.columns(scalars=vs), recording=self.rec)
            ts.clear()
            vs.clear()

    def flush_due(self, t_s: float) -> None:
        """Start a round of sends if ``flush_s`` has passed since the last one began, and
        send up to ``per_call`` columns of the present round."""
        if not self._pending and t_s >= self._next_flush_s:
            self._next_flush_s = t_s + self.flush_s
            self._pending = list(self._cols)
        for _ in range(min(self.per_call, len(self._pending))):
            self._send(self._pending.pop())

    def flush(self) -> None:
        """Send every gathered column now."""
        self._pending = []
        for path in self._cols:
            self._send(path)


#: where the log functions write: a stream (every value logged at once) or its columns
Stream = rr.RecordingStream | ScalarColumns


def warm_up() -> None:
    """Log one of each archetype the dashboard uses into a throwaway in-memory recording:
    rerun's Python API sets each type up on its first use (~75 ms for the hand's first frame
    here, several times that under a loaded machine's real-time loops), which a service
    should pay before its loop starts, not in its first tick."""
    rec = rr.RecordingStream("teleop-warm-up", recording_id="warm-up", send_properties=False)
    rec.memory_recording()
    rec.set_time(TIMELINE, duration=0.0)
    rec.log("s", rr.Scalars(0.0))
    rr.send_columns("c", indexes=[rr.TimeColumn(TIMELINE, duration=[0.0, 0.1])],
                    columns=rr.Scalars.columns(scalars=[0.0, 1.0]), recording=rec)
    rec.log("b", rr.BarChart([0.0, 1.0]))
    rec.log("l", rr.LineStrips2D([[(0.0, 0.0), (1.0, 1.0)]], colors=(1, 2, 3), radii=0.001))
    rec.log("p", rr.Points2D([(0.0, 0.0)], colors=[(1, 2, 3)], radii=0.001))
    rec.log("e", rr.TextLog("warm-up", level="INFO"))
    rec.disconnect()


def _rec(out: Stream) -> rr.RecordingStream:
    return out.rec if isinstance(out, ScalarColumns) else out


def set_time(rec: Stream, t_s: float) -> None:
    """Set the ``time`` timeline (seconds since the session epoch)."""
    if isinstance(rec, ScalarColumns):
        rec.t_s = t_s
        rec = rec.rec
    rec.set_time(TIMELINE, duration=t_s)


def _scalar(rec: Stream, path: str, value: float) -> None:
    if math.isfinite(value):
        if isinstance(rec, ScalarColumns):
            rec.add(path, value)
        else:
            rec.log(path, rr.Scalars(value))


def _physics(rec: Stream, side: str, physics_j: tuple[float, float] | None) -> None:
    if physics_j is not None:
        _scalar(rec, f"{side}/physics_delivered_j", physics_j[0])
        _scalar(rec, f"{side}/physics_taken_j", physics_j[1])


def log_rejects(rec: Stream, t_s: float, role: str,
                by_reason: Sequence[tuple[str, int]]) -> None:
    """Cumulative counts of the messages ``role``'s bus rejected, one series per reason
    (``malformed``, ``out_of_range``, ``stale_seq``, ``seq_jump``, ``energy_jump``, ...)."""
    set_time(rec, t_s)
    for reason, n in by_reason:
        _scalar(rec, f"rejects/{role}/{reason}", float(n))


def log_master(rec: Stream, t_s: float, *, trigger_position_m: float,
               displayed_force_n: float, tank_j: float, port_in_j: float, port_out_j: float,
               delay_s: float | None, model_force_n: float = math.nan,
               physics_j: tuple[float, float] | None = None) -> None:
    """The master's signals; ``port_in_j``/``port_out_j`` are the cumulative energy taken
    from / delivered to the operator; ``delay_s`` is the achieved controller->master delay;
    ``model_force_n`` the contact model the master renders locally (felt force);
    ``physics_j`` the virtual operator's physical work (delivered to it, taken from it)."""
    set_time(rec, t_s)
    _physics(rec, "master", physics_j)
    _scalar(rec, "master/trigger_position_m", trigger_position_m)
    _scalar(rec, "master/displayed_force_n", displayed_force_n)
    _scalar(rec, "master/model_force_n", model_force_n)
    _scalar(rec, "master/tank_j", tank_j)
    _scalar(rec, "master/port_in_j", port_in_j)
    _scalar(rec, "master/port_out_j", port_out_j)
    if delay_s is not None:
        _scalar(rec, "links/controller_to_master/delay_s", delay_s)


def log_controller(rec: Stream, t_s: float, *, setpoints_rad: Sequence[float],
                   commanded_force_n: float, energy_stored_j: float,
                   master_delay_s: float | None, hand_delay_s: float | None,
                   measured_force_n: float = math.nan) -> None:
    """The controller's signals and the achieved delays of the links into it;
    ``measured_force_n``: the hand's pressures through the force map at full gain (the true
    force the operator should feel)."""
    set_time(rec, t_s)
    for i, sp in enumerate(setpoints_rad, start=1):
        _scalar(rec, f"controller/setpoint_rad/f{i}", sp)
    _scalar(rec, "controller/commanded_force_n", commanded_force_n)
    _scalar(rec, "controller/measured_force_n", measured_force_n)
    _scalar(rec, "controller/energy_stored_j", energy_stored_j)
    if master_delay_s is not None:
        _scalar(rec, "links/master_to_controller/delay_s", master_delay_s)
    if hand_delay_s is not None:
        _scalar(rec, "links/hand_to_controller/delay_s", hand_delay_s)


def finger_drawing(proximal_rad: float, distal_rad: float, index: int
                   ) -> tuple[list[tuple[float, float]], list[tuple[float, float]],
                              list[tuple[float, float]]]:
    """Planar drawing of one finger: link polyline, tendon polyline, sensor points.

    The finger lies along +x when open and curls towards -y as the joints flex.
    """
    ox = index * _FINGER_SPACING_M
    a1, a2 = -proximal_rad, -(proximal_rad + distal_rad)
    c1, s1, c2, s2 = math.cos(a1), math.sin(a1), math.cos(a2), math.sin(a2)
    j = (ox + _PROXIMAL_M * c1, _PROXIMAL_M * s1)
    tip = (j[0] + _DISTAL_M * c2, j[1] + _DISTAL_M * s2)
    links = [(ox, 0.0), j, tip]
    # tendon runs on the palm (inner, -y rotated) side of each link
    n1 = (s1 * _TENDON_OFFSET_M, -c1 * _TENDON_OFFSET_M)
    n2 = (s2 * _TENDON_OFFSET_M, -c2 * _TENDON_OFFSET_M)
    tendon = [(ox + n1[0], n1[1]), (j[0] + n1[0], j[1] + n1[1]),
              (j[0] + n2[0], j[1] + n2[1]), (tip[0] + n2[0], tip[1] + n2[1])]
    sensors = [(ox + d * c1 + n1[0], d * s1 + n1[1]) for d in _PROX_SENSORS_M]
    sensors += [(j[0] + d * c2 + n2[0], j[1] + d * s2 + n2[1]) for d in _DIST_SENSORS_M]
    return links, tendon, sensors


def log_hand(rec: Stream, t_s: float, reading: HandReading, *, tank_j: float,
             port_in_j: float, port_out_j: float, delay_s: float | None,
             pictures: bool = True, physics_j: tuple[float, float] | None = None) -> None:
    """The hand's state, pressures, drawing and energy; ``delay_s`` is controller->hand;
    the drawing and the pressure bars only with ``pictures`` (they cost ~2 ms a call);
    ``physics_j`` the simulated fingers' physical work on the object (delivered, taken)."""
    set_time(rec, t_s)
    _physics(rec, "hand", physics_j)
    links, tendons, points, colors = [], [], [], []
    pressures: list[float] = []
    for i, f in enumerate(reading.fingers):
        _scalar(rec, f"hand/finger{i + 1}/proximal_rad", f.proximal_rad)
        _scalar(rec, f"hand/finger{i + 1}/distal_rad", f.distal_rad)
        if not pictures:
            continue
        lk, td, ss = finger_drawing(f.proximal_rad, f.distal_rad, i)
        links.append(lk)
        tendons.append(td)
        points += ss
        colors += [(230, 40, 40) if c else (150, 150, 150) for c in f.contact]
        pressures += [float(p) for p in f.pressure]
    if pictures:
        out = _rec(rec)
        out.log("hand/pressure", rr.BarChart(pressures))
        out.log("hand/drawing/links", rr.LineStrips2D(links, colors=(200, 200, 200),
                                                      radii=0.004))
        out.log("hand/drawing/tendon", rr.LineStrips2D(tendons, colors=(60, 120, 220),
                                                       radii=0.001))
        out.log("hand/drawing/sensors", rr.Points2D(points, colors=colors, radii=0.003))
    _scalar(rec, "hand/servo_fault_trips", float(reading.servo_fault_trips))
    _scalar(rec, "hand/servo_safe", float(reading.servo_safe))
    _scalar(rec, "hand/tank_j", tank_j)
    _scalar(rec, "hand/port_in_j", port_in_j)
    _scalar(rec, "hand/port_out_j", port_out_j)
    if delay_s is not None:
        _scalar(rec, "links/controller_to_hand/delay_s", delay_s)


def log_event(rec: rr.RecordingStream, t_s: float, role: str, text: str,
              level: str = "INFO") -> None:
    """One line in the event log (passivity limiting, watchdog, dropped messages)."""
    set_time(rec, t_s)
    rec.log("events", rr.TextLog(f"[{role}] {text}", level=level))
