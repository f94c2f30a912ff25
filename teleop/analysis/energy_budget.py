"""Where the joules go, grasp by grasp: the physical audit beside the controllers' books.

For a lockstep run of the whole loop (``services.lockstep.LockstepResult`` or anything with
the same arrays), :func:`grasp_budget` splits the run into the operator's grasp cycles and
reports, per cycle, the net work delivered at each physical port (from the simulated operator
and object: the audit), the hand ledger's net (servo-spring energy paid minus credited), and
how much all tanks and the store together gained or lost.  ``docs/controllers.md`` quotes it.

Command line (lockstep, virtual time)::

    teleop budget --seconds 27 --set master.virtual.style=soft --json -
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from teleop.analysis.grasps import after_first

__all__ = ["GraspBudget", "grasp_budget", "format_budget"]


@dataclass(frozen=True, slots=True)
class GraspBudget:
    """One grasp cycle's energy flows (J, net over the cycle; + = delivered / gained)."""

    index: int
    t_start_s: float
    t_end_s: float
    operator_net_j: float  # audit: work on the operator minus work the operator did
    object_net_j: float  # audit: work on the object minus work it gave back
    hand_ledger_net_j: float  # hand passivity layer: paid minus credited
    master_ledger_net_j: float
    stores_change_j: float  # master tank + controller store + hand tank
    peak_pressure: float


def _delta(a: Any, i0: int, i1: int) -> float:
    return float(a[i1] - a[i0]) if a is not None else float("nan")


def grasp_budget(r: Any, cycle_s: float) -> tuple[GraspBudget, ...]:
    """Per complete ``cycle_s`` cycle of ``r`` (a LockstepResult), its :class:`GraspBudget`."""
    if cycle_s <= 0:
        raise ValueError("cycle_s must be positive")
    t = np.asarray(r.t_s)
    n = int(np.floor((t[-1] + 1e-9) / cycle_s)) if t.size else 0
    stores = r.master_tank_j + r.controller_store_j + r.hand_tank_j
    rows = []
    for k in range(n):
        i0, i1 = (int(v) for v in np.searchsorted(t, [k * cycle_s, (k + 1) * cycle_s - 1e-9]))
        i1 = min(i1, t.size - 1)
        rows.append(GraspBudget(
            index=k + 1, t_start_s=float(t[i0]), t_end_s=float(t[i1]),
            operator_net_j=_delta(r.audit_operator_delivered_j, i0, i1)
            - _delta(r.audit_operator_taken_j, i0, i1),
            object_net_j=_delta(r.audit_environment_delivered_j, i0, i1)
            - _delta(r.audit_environment_taken_j, i0, i1),
            hand_ledger_net_j=_delta(r.hand_port_out_j, i0, i1) - _delta(r.hand_port_in_j, i0, i1),
            master_ledger_net_j=_delta(r.master_port_out_j, i0, i1)
            - _delta(r.master_port_in_j, i0, i1),
            stores_change_j=_delta(stores, i0, i1),
            peak_pressure=float(np.nanmax(r.pressure[i0:i1 + 1])) if i1 > i0 else float("nan")))
    return tuple(rows)


def format_budget(rows: tuple[GraspBudget, ...]) -> str:
    """A text table of the rows, then the weakest grasp over the first and the first against
    the next three (:func:`teleop.analysis.grasps.after_first`)."""
    head = (f"{'grasp':>5} {'operator J':>11} {'object J':>10} {'hand ledger J':>14} "
            f"{'master ledger J':>16} {'stores J':>9} {'peak p':>7}")
    lines = [head, "-" * len(head)]
    for b in rows:
        lines.append(f"{b.index:>5} {b.operator_net_j:>+11.4f} {b.object_net_j:>+10.4f} "
                     f"{b.hand_ledger_net_j:>+14.3f} {b.master_ledger_net_j:>+16.4f} "
                     f"{b.stores_change_j:>+9.3f} {b.peak_pressure:>7.0f}")
    peaks = [b.peak_pressure for b in rows]
    if peaks and peaks[0] > 0:  # (a nan first peak fails the test: no reference)
        seen = [p for p in peaks if math.isfinite(p)]
        blank = len(peaks) - len(seen)
        lines.append(f"weakest over the first (peak pressure): {min(seen) / peaks[0]:.2f}"
                     + (f" ({blank} of {len(peaks)} cycles without pressure samples)"
                        if blank else ""))
    after = after_first(peaks, [b.index for b in rows], "peak_pressure")
    if after is not None:
        lines.append(after.describe())
    return "\n".join(lines)
