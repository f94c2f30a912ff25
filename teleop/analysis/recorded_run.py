"""A ``teleop up --record DIR`` run judged afterwards: does the loop keep working?

Three questions, answered from the three services' recordings (``master.csv``, ``hand.csv``,
``controller.csv``; the hand and controller sampled and held on the master's clock, all three
share the launcher's epoch):

* every grasp against the first (:func:`teleop.analysis.grasps.curl_grasps`:
  peak pressure, the fingers' curl held 0.1 s, felt force);
* whether an energy store sat empty while the operator asked for motion: the master's and the
  hand's tanks and the controller's store below ``floor_j`` while the trigger is closed past
  the grasp threshold (a closed trigger with an empty tank is a hand that ignores it);
* which safety guards fired (watchdogs, servo-fault safe state, contact guards), for how long;

and, with the virtual operator and the simulated hand, whether the run was passive by the
physics (:mod:`teleop.analysis.port_audit`: the work done at the trigger and on the object
against the tanks' initial energy, not the controllers' books).

A grasp during which a service's recording stops for more than :data:`GAP_S` (the process was
stalled or starved: a stalled master's operator script jumps ahead, a stalled hand misses its
samples) is *interrupted*: listed with the gap, not judged; when the first grasp is
interrupted, the first uninterrupted one is the reference.  A store empty during such a gap
or :data:`RECOVERY_S` after it is reported apart and not counted.

Times are on the recordings' own clock (the launcher's epoch: the services start a few
seconds after it).

Example::

    report = judge_recorded_run(read_run_dir("runs/a"), threshold_m=0.0025)
    print(format_recorded_run(report))
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from teleop.analysis.grasps import GraspSeries, GraspStats, curl_grasps
from teleop.analysis.port_audit import PortAudit, recorded_audit
from teleop.errors import RecordingError
from teleop.recording import Recording, read_recording

Array = NDArray[np.float64]

__all__ = ["RunRecordings", "EmptySpells", "GuardTime", "RecordingGap", "RecordedRunReport",
           "read_run_dir", "judge_recorded_run", "format_recorded_run", "EMPTY_FLOOR_J",
           "GAP_S", "RECOVERY_S"]

#: an energy store below this is empty (J)
EMPTY_FLOOR_J = 0.005
#: a service's recording silent longer than this (s) interrupts the grasps it overlaps: ten of
#: the hand's 25 ms samples, far above the 5-40 ms stalls of a busy machine
GAP_S = 0.25
#: after a recording gap the loop is given this long (s) before an empty store counts again:
#: the stalled service's first messages after it (the energy sent to a stalled hand meanwhile
#: arrives with them)
RECOVERY_S = 0.5

_ROLES = ("master", "hand", "controller")
#: (role, column, what it means): 0/1 flags, time spent at 1 is reported
_FLAGS = (("master", "watchdog", "master force-command watchdog"),
          ("controller", "watchdog", "controller hand-state watchdog"),
          ("hand", "watchdog", "hand command watchdog"),
          ("hand", "servo_safe", "hand held safe on servo error bits"),
          # the hand's passivity layer held a set-point back because its tank could not pay
          # (a tank held at its floor reads above the empty line: this is where it shows)
          ("hand", "limited", "hand set-point held back by its tank"))
#: (role, column, what it means): counts of fingers flagged per tick, time with any reported
_FINGER_FLAGS = (("hand", "yielding", "a finger's contact yielding"),
                 ("hand", "unseen_contact", "a finger stalled on a contact its cells miss"),
                 ("hand", "cells_low", "a finger's cells reading below its servo's load"))


@dataclass(frozen=True, slots=True)
class RunRecordings:
    """The recordings of one run (``controller`` may be missing: it is then not judged)."""

    master: Recording
    hand: Recording
    controller: Recording | None
    source: str


@dataclass(frozen=True, slots=True)
class EmptySpells:
    """When one energy store sat below the floor while the trigger was closed."""

    store: str  # "master tank", "hand tank", "controller store"
    closed_s: float  # time the trigger was closed past the grasp threshold
    empty_s: float  # of it, time this store was below the floor
    spells: int  # separate stretches
    longest_s: float
    longest_at_s: float  # start of the longest (nan: none)
    min_j: float  # the store's lowest value while the trigger was closed
    excused_s: float = 0.0  # empty during a recording gap or RECOVERY_S after it: not counted

    @property
    def empty_fraction(self) -> float:
        return self.empty_s / self.closed_s if self.closed_s > 0 else math.nan


@dataclass(frozen=True, slots=True)
class GuardTime:
    """How long one guard was active in the run."""

    what: str
    active_s: float
    spells: int  # separate stretches
    first_at_s: float  # nan: never


@dataclass(frozen=True, slots=True)
class RecordingGap:
    """A stretch in which one service's recording has no sample (its process stalled)."""

    role: str  # "master", "hand", "controller"
    at_s: float  # the last sample before it
    gap_s: float  # to the next sample

    def overlaps(self, t_start_s: float, t_end_s: float) -> bool:
        return self.at_s < t_end_s and self.at_s + self.gap_s > t_start_s


def _interrupted(gaps: tuple[RecordingGap, ...], g: GraspStats) -> bool:
    """Whether any of ``gaps`` overlaps grasp ``g`` (it is then not judged)."""
    return any(x.overlaps(g.t_start_s, g.t_end_s) for x in gaps)


@dataclass(frozen=True, slots=True)
class RecordedRunReport:
    source: str
    duration_s: float
    threshold_m: float
    floor_j: float
    grasps: GraspSeries  # every complete grasp, over the reference (the first judged)
    empty: tuple[EmptySpells, ...]
    guards: tuple[GuardTime, ...]
    gaps: tuple[RecordingGap, ...] = ()  # every one longer than gap_bound_s
    gap_bound_s: float = GAP_S
    audit: PortAudit | None = None  # the physical energy audit (simulated ports only)

    def interrupted(self, index: int) -> bool:
        """Whether a recording gap overlaps grasp ``index`` (it is then not judged)."""
        return _interrupted(self.gaps, self.grasps.grasps[index])

    @property
    def judged(self) -> GraspSeries:
        """The grasps no recording gap interrupted (the first of them is the reference)."""
        return GraspSeries(tuple(g for g in self.grasps.grasps
                                 if not _interrupted(self.gaps, g)))

    @property
    def reference_index(self) -> int:
        """The grasp the ratios are over: the first judged (0 when none is)."""
        j = self.judged.grasps
        return j[0].index if j else 0

    def as_dict(self) -> dict[str, object]:
        g = self.judged
        rows = self.grasps.rows()
        for k, row in enumerate(rows):
            row["interrupted"] = self.interrupted(k)
        return {"source": self.source, "duration_s": self.duration_s,
                "grasp_threshold_m": self.threshold_m, "empty_floor_j": self.floor_j,
                "grasp_count": len(rows), "judged_count": len(g.grasps),
                "min_pressure_ratio": g.min_pressure_ratio,
                "min_closure_ratio": g.min_closure_ratio, "min_felt_ratio": g.min_felt_ratio,
                "felt_not_held": [x.index for x in g.felt_not_held],
                "after_first": (None if (a := g.after_first()) is None else
                                {"measure": a.measure, "early": a.early,
                                 "early_best_over_first": a.early_best_over_first,
                                 "later_weakest_over_early_best":
                                     a.later_weakest_over_early_best,
                                 "later_weakest_grasp": a.later_weakest_index}),
                "grasps": rows,
                "gap_bound_s": self.gap_bound_s,
                "gaps": [{"role": x.role, "at_s": x.at_s, "gap_s": x.gap_s} for x in self.gaps],
                "empty": [{"store": e.store, "closed_s": e.closed_s, "empty_s": e.empty_s,
                           "empty_fraction": e.empty_fraction, "spells": e.spells,
                           "longest_s": e.longest_s, "longest_at_s": e.longest_at_s,
                           "min_j": e.min_j, "excused_s": e.excused_s} for e in self.empty],
                "guards": [{"what": x.what, "active_s": x.active_s, "spells": x.spells,
                            "first_at_s": x.first_at_s}
                           for x in self.guards],
                "energy_audit": (self.audit.as_dict() if self.audit is not None
                                 else {"audited": False})}


def read_run_dir(path: str | Path) -> RunRecordings:
    """The recordings ``teleop up --record DIR`` wrote (master and hand required)."""
    d = Path(path)
    if not d.is_dir():
        raise RecordingError(f"{d}: no such directory (give the DIR of teleop up --record DIR)")
    recs: dict[str, Recording | None] = {}
    for role in _ROLES:
        f = d / f"{role}.csv"
        if not f.exists():
            if role == "controller":
                recs[role] = None
                continue
            raise RecordingError(f"{f}: missing (teleop up --record writes master.csv, "
                                 "hand.csv and controller.csv)")
        rec = read_recording(f)
        if len(rec.t_s) < 2:
            raise RecordingError(f"{f}: fewer than two samples")
        recs[role] = rec
    master, hand = recs["master"], recs["hand"]
    assert master is not None and hand is not None
    return RunRecordings(master, hand, recs["controller"], str(d))


def _spans(t: Array, on: NDArray[np.bool_]) -> list[tuple[float, float]]:
    """(start, duration) of every stretch where ``on`` holds (a sample lasts to the next)."""
    dt = np.diff(t, append=t[-1])
    edges = np.flatnonzero(np.diff(np.concatenate([[0], on.astype(np.int8), [0]])))
    return [(float(t[a]), float(dt[a:b].sum())) for a, b in zip(edges[::2], edges[1::2],
                                                                 strict=True)]


def _empty(store: str, t: Array, level_j: Array, closed: NDArray[np.bool_],
           floor_j: float, excused: NDArray[np.bool_]) -> EmptySpells:
    dt = np.diff(t, append=t[-1])
    seen = closed & np.isfinite(level_j)
    empty_any = seen & (level_j < floor_j)
    empty = empty_any & ~excused
    spans = _spans(t, empty)
    longest = max(spans, key=lambda s: s[1], default=(math.nan, 0.0))
    return EmptySpells(store, float(dt[seen].sum()), float(dt[empty].sum()), len(spans),
                       longest[1], longest[0],
                       float(level_j[seen].min()) if seen.any() else math.nan,
                       float(dt[empty_any & excused].sum()))


def _gaps(role: str, rec: Recording, min_gap_s: float) -> list[RecordingGap]:
    dt = np.diff(rec.t_s)
    return [RecordingGap(role, float(rec.t_s[i]), float(dt[i]))
            for i in np.flatnonzero(dt > min_gap_s)]


def judge_recorded_run(run: RunRecordings, threshold_m: float,
                       floor_j: float = EMPTY_FLOOR_J, gap_s: float = GAP_S) -> RecordedRunReport:
    """Every grasp against the first judged, the stores' empty spells and the guards of one
    run, and the recording gaps longer than ``gap_s``."""
    m, h, c = run.master, run.hand, run.controller
    t = m.t_s
    pressure = np.column_stack([h.held(f"pressure_f{i // 9 + 1}_{i % 9}", t)
                                for i in range(27)])
    prox = np.column_stack([h.held(f"proximal_angle_rad_f{i}", t) for i in (1, 2, 3)])
    dist = np.column_stack([h.held(f"distal_angle_rad_f{i}", t) for i in (1, 2, 3)])
    trigger = m.column("trigger_position_m")
    grasps = curl_grasps(t, trigger, pressure, prox, dist, m.column("displayed_force_n"),
                         threshold_m, m.column("force_command_n")
                         if m.has("force_command_n") else None)
    closed = np.nan_to_num(trigger, nan=0.0) > threshold_m
    stores = [("master tank", m.column("tank_j")), ("hand tank", h.held("tank_j", t))]
    if c is not None:
        stores.append(("controller store", c.held("store_j", t)))
    recs = {"master": m, "hand": h, "controller": c}
    gaps = tuple(x for role, rec in recs.items() if rec is not None
                 for x in _gaps(role, rec, gap_s))
    excused = np.zeros(len(t), dtype=bool)
    for x in gaps:
        excused |= (t >= x.at_s) & (t < x.at_s + x.gap_s + RECOVERY_S)
    empty = tuple(_empty(name, t, level, closed, floor_j, excused) for name, level in stores)
    guards = []
    for role, col, what in _FLAGS + _FINGER_FLAGS:
        rec = recs[role]
        if rec is None or not rec.has(col):
            continue
        spans = _spans(rec.t_s, np.nan_to_num(rec.column(col)) > 0.5)
        guards.append(GuardTime(what, sum(s[1] for s in spans), len(spans),
                                spans[0][0] if spans else math.nan))
    hit = [_interrupted(gaps, g) for g in grasps.grasps]
    if hit and hit[0] and not all(hit):
        grasps = grasps.rebased(hit.index(False))
    scale = m.meta_value("energy_scale", "1")
    try:
        rho = float(scale or "1")
    except ValueError:
        raise RecordingError(f"{m.source}: energy_scale {scale!r} is not a number") from None
    return RecordedRunReport(run.source, float(t[-1] - t[0]), threshold_m, floor_j, grasps,
                             empty, tuple(guards), gaps, gap_s, recorded_audit(m, h, c, rho))


def format_recorded_run(r: RecordedRunReport, every: int = 1) -> str:
    """The per-grasp table, then the stores and the guards, one line each, then the
    physical energy audit."""
    from teleop.analysis.grasps import format_grasps
    from teleop.analysis.port_audit import format_audit

    g = r.grasps
    lost = [k for k in range(len(g.grasps)) if r.interrupted(k)]
    lines = [f"{r.source}: {r.duration_s:.0f} s, {len(g.grasps)} complete grasps "
             f"(trigger past {r.threshold_m * 1000:.2f} mm)"
             + (f", {len(lost)} interrupted by a recording gap, not judged" if lost else "")]
    j = r.judged
    if j.grasps:
        pressure = (f"peak pressure {j.min_pressure_ratio:.2f}"
                    if math.isfinite(j.min_pressure_ratio) else "peak pressure - (none read)")
        k = r.reference_index
        ref = "first" if k == 0 else f"grasp {k}"
        lines.append(f"weakest over {ref}: {pressure}, closure {j.min_closure_ratio:.2f}, "
                     f"felt force {j.min_felt_ratio:.2f}")
        after = j.after_first()
        if after is not None:
            lines.append(after.describe())
        ghost = j.felt_not_held
        if ghost:
            shown = ", ".join(str(x.index) for x in ghost[:12]) + (", ..." if len(ghost) > 12
                                                                  else "")
            lines.append(f"felt, not held: {len(ghost)} grasps (grasp {shown}) felt at "
                         f"{min(x.felt_ratio for x in ghost):.2f} or more of "
                         f"{'the first' if k == 0 else ref}'s force with "
                         f"{max(x.pressure_ratio for x in ghost):.2f} or less of its "
                         "pressure: the operator feels a grasp the hand is not making")
    if g.grasps:
        lines.append(format_grasps(g, every, marked=frozenset(lost)))
    if r.gaps:
        lines.append(f"recording gaps (a service silent longer than {r.gap_bound_s:g} s): "
                     f"{len(r.gaps)}")
        for x in r.gaps[:10]:
            over = [k for k in lost if x.overlaps(g.grasps[k].t_start_s, g.grasps[k].t_end_s)]
            lines.append(f"  {x.role:10s} {x.gap_s:6.2f} s after {x.at_s:.1f} s"
                         + (f" (grasp {', '.join(map(str, over))})" if over else ""))
    lines.append(f"energy stores while the trigger is closed (empty: below "
                 f"{r.floor_j * 1000:g} mJ):")
    for e in r.empty:
        where = (f", longest {e.longest_s:.2f} s at {e.longest_at_s:.1f} s" if e.spells else "")
        excused = (f"; {e.excused_s:.2f} s more during recording gaps, not counted"
                   if e.excused_s > 0 else "")
        lines.append(f"  {e.store:17s} lowest {e.min_j:.3f} J; empty {e.empty_s:.2f} s of "
                     f"{e.closed_s:.0f} s ({100 * e.empty_fraction:.2f} %) in {e.spells} "
                     f"spells{where}{excused}")
    lines.append("guards:")
    for x in r.guards:
        when = (f" in {x.spells} spells, the first at {x.first_at_s:.1f} s"
                if x.spells else "")
        lines.append(f"  {x.what:48s} {x.active_s:7.2f} s{when}")
    lines.append(format_audit(r.audit))
    return "\n".join(lines)
