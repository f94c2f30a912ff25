"""Every grasp of a run judged against the first (endurance; lockstep and live recordings).

A grasp is found from the trigger alone: it starts when the trigger closes past
``threshold_m`` (after having opened below half of it: hysteresis) and lasts until the next
such start (so the hand's delayed response and the release belong to it); a grasp still
closed at the end of the run is incomplete and dropped.  The threshold is low (a tenth of the
travel by default) because the displayed force holds the trigger well short of where the
operator aims while the hand is in contact.
Per grasp: peak pressure (largest taxel of any finger), closure (the largest finger angle held
for ``hold_s``, 0.1 s: a one-sample overshoot of a link at an impact is not how far the hand
closed; the plain largest angle is kept beside it as ``peak_closure_rad``), felt force (largest
displayed force), and each over the first grasp's.

Example::

    g = analyse_grasps(t, trigger_m, pressure, proximal_rad, displayed_n, threshold_m=0.006)
    g.min_pressure_ratio      # the weakest grasp's peak pressure over the first's
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import minimum_filter1d

if TYPE_CHECKING:
    from teleop.config import TeleopConfig

Array = NDArray[np.float64]

__all__ = ["GraspStats", "GraspSeries", "grasp_windows", "held_max", "analyse_grasps",
           "format_grasps", "HOLD_S", "curl_grasps", "grasp_threshold_m"]

#: a closure counts when a finger holds it this long (s): longer than an impact's overshoot
#: (one or two 25 ms hand samples), shorter than any hold of a grasp
HOLD_S = 0.1
#: a grasp felt at least this fraction of the reference's force ...
FELT_AS_REFERENCE = 0.9
#: ... with its peak pressure under this fraction of the reference's, and the force its own
#: pressure asks for (where recorded) under this fraction of what was felt: felt, not held
#: (:attr:`GraspSeries.felt_not_held`)
HELD_UNDER = 0.5


@dataclass(frozen=True, slots=True)
class GraspStats:
    """One grasp."""

    index: int
    t_start_s: float
    t_end_s: float
    peak_pressure: float
    closure_rad: float
    felt_force_n: float
    pressure_ratio: float  # over the first grasp's (nan when the first has none)
    closure_ratio: float
    felt_ratio: float
    peak_closure_rad: float = math.nan  # the largest angle, however briefly
    #: the largest force the hand's measured pressure asked the trigger for (the
    #: controller's measured-force command; nan: not recorded)
    measured_force_n: float = math.nan


#: grasps after the first that :meth:`GraspSeries.after_first` compares the first with
EARLY_GRASPS = 3


@dataclass(frozen=True, slots=True)
class AfterFirst:
    """The first grasp against the next few, and the rest against those (one measure)."""

    measure: str  # "peak_pressure" or "closure_rad"
    early: int  # how many grasps after the first make the early best
    early_best_over_first: float
    later_weakest_over_early_best: float
    later_weakest_index: int

    def describe(self) -> str:
        """One line for the report."""
        what = "peak pressure" if self.measure == "peak_pressure" else "closure"
        return (f"after the first ({what}): the best of the next {self.early} "
                f"{self.early_best_over_first:.2f} of the first; the weakest later grasp "
                f"(grasp {self.later_weakest_index}) {self.later_weakest_over_early_best:.2f} "
                f"of that best")


def after_first(values: Sequence[float], indices: Sequence[int], measure: str,
                early: int = EARLY_GRASPS) -> AfterFirst | None:
    """:class:`AfterFirst` of one measure of successive grasps (grasp numbers ``indices``);
    None with fewer than ``early + 2`` grasps or any value not finite."""
    if len(values) < early + 2 or not all(math.isfinite(v) for v in values):
        return None
    best = max(values[1:1 + early])
    weakest = min(range(1 + early, len(values)), key=lambda k: values[k])
    return AfterFirst(measure, early, _ratio(best, values[0]), _ratio(values[weakest], best),
                      indices[weakest])


@dataclass(frozen=True, slots=True)
class GraspSeries:
    """All complete grasps of a run."""

    grasps: tuple[GraspStats, ...]

    @property
    def min_pressure_ratio(self) -> float:
        """The weakest grasp's peak pressure over the first's (nan: fewer than one grasp)."""
        vals = [g.pressure_ratio for g in self.grasps]
        return min(vals) if vals and all(math.isfinite(v) for v in vals) else math.nan

    @property
    def min_felt_ratio(self) -> float:
        vals = [g.felt_ratio for g in self.grasps if math.isfinite(g.felt_ratio)]
        return min(vals) if vals else math.nan

    @property
    def min_closure_ratio(self) -> float:
        vals = [g.closure_ratio for g in self.grasps if math.isfinite(g.closure_ratio)]
        return min(vals) if vals else math.nan

    @property
    def felt_not_held(self) -> tuple[GraspStats, ...]:
        """Grasps the operator felt like the reference (felt force at least
        :data:`FELT_AS_REFERENCE` of its) while the hand held under :data:`HELD_UNDER` of its
        peak pressure: a grasp felt that the hand was not making (a hand whose tank holds its
        set-points back while the master renders the object's contact model:
        docs/controllers.md, "Hard squeezes over ten minutes").  Where the measured-force
        command is recorded, also only while it stayed under :data:`HELD_UNDER` of the felt
        force: a pressure far under the reference's can still ask for the full display (the
        trigger's force saturates), and such a grasp is felt as held.  None without
        pressure ratios (a hand without tactile cells)."""
        return tuple(g for g in self.grasps
                     if math.isfinite(g.felt_ratio) and math.isfinite(g.pressure_ratio)
                     and g.felt_ratio >= FELT_AS_REFERENCE and g.pressure_ratio < HELD_UNDER
                     and not g.measured_force_n >= HELD_UNDER * g.felt_force_n)

    @property
    def weakest(self) -> GraspStats | None:
        """The grasp with the lowest peak pressure over the first's; by closure when the
        pressures give no ratio (a hand without tactile cells reads zeros)."""
        gs = self.grasps
        if gs and all(math.isfinite(g.pressure_ratio) for g in gs):
            return min(gs, key=lambda g: g.pressure_ratio)
        finite = [g for g in gs if math.isfinite(g.closure_ratio)]
        return min(finite, key=lambda g: g.closure_ratio) if finite else None

    def after_first(self, early: int = EARLY_GRASPS) -> AfterFirst | None:
        """The first grasp against the next ``early`` and the rest against those, by peak
        pressure (by closure when the pressures give no ratio): a first grasp out of line
        with the next ones (blind under a long delay, or an overshoot while the rendered
        contact model still fits a stiffening object) reads as a loss, or hides one, in the
        ratios over the first alone.  None with fewer than ``early + 2`` grasps."""
        gs = self.grasps
        vals = [g.peak_pressure if math.isfinite(g.pressure_ratio) else math.nan for g in gs]
        idx = [g.index for g in gs]
        return (after_first(vals, idx, "peak_pressure", early)
                or after_first([g.closure_rad for g in gs], idx, "closure_rad", early))

    def rebased(self, ref: int) -> GraspSeries:
        """The same grasps with every ratio over grasp ``ref``'s (a position in
        :attr:`grasps`): the reference when the first cannot be one."""
        r = self.grasps[ref]
        return GraspSeries(tuple(
            replace(g, pressure_ratio=_ratio(g.peak_pressure, r.peak_pressure),
                    closure_ratio=_ratio(g.closure_rad, r.closure_rad),
                    felt_ratio=_ratio(g.felt_force_n, r.felt_force_n))
            for g in self.grasps))

    def rows(self) -> list[dict[str, float]]:
        """JSON rows (nan left to the writer)."""
        return [{"grasp": g.index, "t_start_s": g.t_start_s, "t_end_s": g.t_end_s,
                 "peak_pressure": g.peak_pressure, "closure_rad": g.closure_rad,
                 "felt_force_n": g.felt_force_n, "pressure_ratio": g.pressure_ratio,
                 "closure_ratio": g.closure_ratio, "felt_ratio": g.felt_ratio,
                 "peak_closure_rad": g.peak_closure_rad,
                 "measured_force_n": g.measured_force_n}
                for g in self.grasps]


def grasp_windows(t_s: Array, trigger_m: Array, threshold_m: float) -> list[tuple[float, float]]:
    """(start, end) of every complete grasp: closing past ``threshold_m`` (after opening below
    half of it) to the next such closing, or the end of the run for the last."""
    t = np.asarray(t_s, float)
    x = np.nan_to_num(np.asarray(trigger_m, float), nan=0.0)
    hi, lo = x > threshold_m, x < 0.5 * threshold_m
    marks = np.where(hi, 1, np.where(lo, -1, 0))
    idx = np.flatnonzero(marks)
    if not idx.size:
        return []
    state = marks[idx]
    change = np.flatnonzero(np.diff(state)) + 1
    starts = [int(idx[0])] if state[0] == 1 else []
    starts += [int(idx[k]) for k in change if state[k] == 1]
    opens = [int(idx[k]) for k in change if state[k] == -1]
    out = []
    for k, i in enumerate(starts):
        if not any(j > i for j in opens):
            break  # still closed at the end: incomplete
        end = t[starts[k + 1]] if k + 1 < len(starts) else t[-1]
        out.append((float(t[i]), float(end)))
    return out


def held_max(t_s: Array, q: Array, hold_s: float = HOLD_S) -> float:
    """The largest value any column of ``q`` ((n, k), sampled and held at ``t_s``) keeps for
    ``hold_s`` or longer (nan when the span is shorter; the plain largest for ``hold_s <=
    0``).  The samples are held onto a grid of a tenth of ``hold_s``; the value kept over a
    window is its smallest sample."""
    t = np.asarray(t_s, float)
    if hold_s <= 0.0:
        return float(np.asarray(q, float).max(initial=-np.inf))
    if len(t) < 2 or t[-1] - t[0] < hold_s:
        return math.nan
    step = hold_s / 10.0
    grid = np.arange(t[0], t[-1], step)
    held = np.asarray(q, float).reshape(len(t), -1)[np.searchsorted(t, grid, "right") - 1]
    kept = minimum_filter1d(held, size=11, axis=0, mode="constant", cval=-np.inf)
    return float(kept.max())


def _ratio(v: float, first: float) -> float:
    return v / first if first > 0 and math.isfinite(first) else math.nan


def analyse_grasps(t_s: Array, trigger_m: Array, pressure: Array, finger_rad: Array,
                   displayed_force_n: Array, threshold_m: float,
                   hold_s: float = HOLD_S,
                   measured_force_n: Array | None = None) -> GraspSeries:
    """Per-grasp peak pressure, closure (held ``hold_s``) and felt force, and each over the
    first grasp's; with ``measured_force_n`` (the controller's measured-force command as the
    master received it), its peak per grasp.

    ``pressure``: (n, k) taxels; ``finger_rad``: (n, fingers) joint angles.
    """
    t = np.asarray(t_s, float)
    p = np.nan_to_num(np.asarray(pressure, float).reshape(len(t), -1), nan=0.0)
    q = np.nan_to_num(np.asarray(finger_rad, float).reshape(len(t), -1), nan=-np.inf)
    f = np.nan_to_num(np.asarray(displayed_force_n, float), nan=0.0)
    fm = (None if measured_force_n is None
          else np.nan_to_num(np.asarray(measured_force_n, float), nan=0.0))
    raw = []
    for a, b in grasp_windows(t, trigger_m, threshold_m):
        m = (t >= a) & (t < b) if b > a else (t >= a)
        raw.append((a, b, float(p[m].max(initial=0.0)), held_max(t[m], q[m], hold_s),
                    float(f[m].max(initial=0.0)), float(q[m].max(initial=-np.inf)),
                    math.nan if fm is None else float(fm[m].max(initial=0.0))))
    if not raw:
        return GraspSeries(())
    _, _, p0, q0, f0, _, _ = raw[0]
    return GraspSeries(tuple(
        GraspStats(i, a, b, pk, cl, fe, _ratio(pk, p0), _ratio(cl, q0), _ratio(fe, f0), top,
                   fmeas)
        for i, (a, b, pk, cl, fe, top, fmeas) in enumerate(raw)))


def grasp_threshold_m(cfg: TeleopConfig) -> float:
    """Trigger closing that marks a grasp: a tenth of what the operator's script closes to
    (in contact the displayed force holds the trigger far short of the script's aim)."""
    return 0.1 * cfg.master.virtual.closed_fraction * cfg.master.travel_m


def curl_grasps(t_s: Array, trigger_m: Array, pressure: Array, proximal_rad: Array,
                distal_rad: Array, displayed_force_n: Array, threshold_m: float,
                measured_force_n: Array | None = None) -> GraspSeries:
    """:func:`analyse_grasps` where a finger's closure is its curl, proximal + distal ((n,
    fingers) each): how far the tendon closed it.  The proximal angle alone is how an
    underactuated finger shares that curl between its links, which differs between grasps of
    equal force (the hard operator on the block: 0.078-0.091 rad at 4,992-4,995 each) and
    overshoots for a sample at an impact."""
    curl = np.asarray(proximal_rad, float) + np.asarray(distal_rad, float)
    return analyse_grasps(t_s, trigger_m, pressure, curl, displayed_force_n, threshold_m,
                          measured_force_n=measured_force_n)


def format_grasps(series: GraspSeries, every: int = 1,
                  marked: frozenset[int] = frozenset()) -> str:
    """A per-grasp table (every ``every``-th grasp, and always the weakest and the last);
    grasps whose index is in ``marked`` (interrupted: not judged) are always shown, ending in
    ``gap``, and are not the weakest."""
    head = (f"{'grasp':>5} {'t_s':>7} {'peak_p':>7} {'p/p0':>6} {'closure':>8} {'c/c0':>6} "
            f"{'felt_N':>7} {'f/f0':>6}")
    lines = [head]
    gs = series.grasps
    weakest = GraspSeries(tuple(g for g in gs if g.index not in marked)).weakest
    for g in gs:
        if g.index % every and g is not weakest and g is not gs[-1] and g.index not in marked:
            continue
        lines.append(f"{g.index:5d} {g.t_start_s:7.1f} {g.peak_pressure:7.0f} "
                     f"{_cell(g.pressure_ratio)} {g.closure_rad:8.3f} "
                     f"{_cell(g.closure_ratio)} {g.felt_force_n:7.2f} {_cell(g.felt_ratio)}"
                     + ("  gap" if g.index in marked else ""))
    return "\n".join(lines)


def _cell(v: float) -> str:
    """A ratio column: ``-`` where there is none (nothing to compare with)."""
    return f"{v:6.2f}" if math.isfinite(v) else f"{'-':>6}"
