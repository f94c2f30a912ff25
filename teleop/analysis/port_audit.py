"""The physical energy audit of a run's two ports: one formula for every reader.

Whether the loop is passive, judged from the simulated physics (the virtual operator's
``sim.operator`` and the object's ``sim.audit``: work done at the operator's trigger and on
the object), never from a controller's own books::

    margin = rho (master initial + taken - delivered at the operator port)
             + hand and controller initial + taken - delivered at the object port   >= 0

in hand-side joules (``rho`` = ``controller.tank.energy_scale``; 1 = plain joules).
:func:`audit_margin_j` is that formula; the lockstep runner, the soak's report and the
recorded runs below all compute it through it.

:func:`recorded_audit` reads it from a ``teleop up --record DIR`` run: the master's and the
hand's recordings carry the cumulative ``audit_delivered_j`` and ``audit_taken_j`` of their
simulated port (columns present only with the virtual operator and the simulated hand), the
tanks' initial energy comes from each side's ledger identity at its first sample
(:func:`ledger_initial_j`).  The margin is evaluated at the hand's samples (40 Hz), the
master's 1 kHz values held (at most one master tick old); the controller's store counts from
its first sample (it can pay nothing before it runs).

Example::

    a = recorded_audit(read_recording("m.csv"), read_recording("h.csv"),
                       read_recording("c.csv"), energy_scale=1.0)
    print(format_audit(a))
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from teleop.recording import Recording

Array = NDArray[np.float64]

__all__ = ["AUDIT_COLUMNS", "PortAudit", "audit_margin_j", "audit_tolerance_j", "format_audit",
           "ledger_initial_j", "recorded_audit"]

#: the cumulative physical work columns a simulated port's recording carries (J)
AUDIT_COLUMNS = ("audit_delivered_j", "audit_taken_j")


def audit_margin_j(initial_j: ArrayLike, energy_scale: float, operator_taken_j: ArrayLike,
                   operator_delivered_j: ArrayLike, environment_taken_j: ArrayLike,
                   environment_delivered_j: ArrayLike) -> Array:
    """The physical passivity margin (hand-side J) at each sample: ``initial`` (already in
    hand-side joules; a scalar or one value per sample) plus ``rho`` times the operator
    port's taken minus delivered plus the object port's taken minus delivered."""
    return (np.asarray(initial_j, float)
            + energy_scale * (np.asarray(operator_taken_j, float)
                              - np.asarray(operator_delivered_j, float))
            + np.asarray(environment_taken_j, float)
            - np.asarray(environment_delivered_j, float))


def audit_tolerance_j(throughput_j: float, initial_j: float, abs_j: float = 1e-6,
                      rel: float = 1e-6) -> float:
    """How far below zero the margin may read before the audit counts energy created:
    rounding of cumulative sums, ``abs_j`` plus ``rel`` of what passed through the ports
    and the tanks' initial energy (the stability classifier's ``energy_tol_j`` and
    ``energy_rel_tol``)."""
    return abs_j + rel * (abs(throughput_j) + abs(initial_j))


def ledger_initial_j(rec: Recording, store: str = "tank_j") -> float:
    """A side's initial energy from its ledger identity at the first sample::

        initial = store + out + sent + dissipated - in - received

    (accounts the recording lacks count 0)."""
    def first(name: str) -> float:
        return float(np.nan_to_num(rec.column(name)[0])) if rec.has(name) else 0.0

    return (first(store) + first("port_out_j") + first("sent_j") + first("dissipated_j")
            - first("port_in_j") - first("received_j"))


@dataclass(frozen=True, slots=True)
class PortAudit:
    """The physical audit of one recorded run (hand-side joules but where said)."""

    t_s: Array  # the samples the margin is evaluated at
    margin_j: Array
    initial_j: float  # rho x master + hand + controller
    energy_scale: float
    operator_delivered_j: float  # at the end, master-side J
    operator_taken_j: float
    environment_delivered_j: float
    environment_taken_j: float
    #: the ledgers' net port energy out minus the physics', at the end, per port (operator
    #: in master-side J): how far the books are from the physics (> 0: the books charged more)
    ledger_gap_operator_j: float = math.nan
    ledger_gap_environment_j: float = math.nan

    @property
    def throughput_j(self) -> float:
        """Energy that passed through both ports, either way (hand-side J)."""
        return (self.energy_scale * (self.operator_delivered_j + self.operator_taken_j)
                + self.environment_delivered_j + self.environment_taken_j)

    @property
    def tolerance_j(self) -> float:
        return audit_tolerance_j(self.throughput_j, self.initial_j)

    @property
    def min_margin_j(self) -> float:
        return float(np.min(self.margin_j))

    @property
    def min_at_s(self) -> float:
        return float(self.t_s[int(np.argmin(self.margin_j))])

    @property
    def generated_j(self) -> float:
        """Largest excess of the energy delivered over the bound (0: passive throughout)."""
        return max(0.0, -self.min_margin_j)

    @property
    def passive(self) -> bool:
        return -self.min_margin_j <= self.tolerance_j

    def as_dict(self) -> dict[str, Any]:
        return {"audited": True, "passive": self.passive, "samples": int(self.margin_j.size),
                "min_margin_j": self.min_margin_j, "min_at_s": self.min_at_s,
                "final_margin_j": float(self.margin_j[-1]),
                "generated_j": self.generated_j, "tolerance_j": self.tolerance_j,
                "initial_j": self.initial_j, "energy_scale": self.energy_scale,
                "operator_delivered_j": self.operator_delivered_j,
                "operator_taken_j": self.operator_taken_j,
                "environment_delivered_j": self.environment_delivered_j,
                "environment_taken_j": self.environment_taken_j,
                "ledger_gap_operator_j": self.ledger_gap_operator_j,
                "ledger_gap_environment_j": self.ledger_gap_environment_j}


def _has_audit(rec: Recording) -> bool:
    return all(rec.has(c) and bool(np.isfinite(rec.column(c)).any()) for c in AUDIT_COLUMNS)


def recorded_audit(master: Recording, hand: Recording, controller: Recording | None,
                   energy_scale: float = 1.0) -> PortAudit | None:
    """The physical audit of a recorded run (None: a port without simulated physics, so no
    audit columns; e.g. a real hand, the dynamixel driver, or a recording from before
    2026-11-29)."""
    if not (_has_audit(master) and _has_audit(hand)):
        return None
    rho = float(energy_scale)
    t = hand.t_s
    od, ot = (master.held(c, t) for c in AUDIT_COLUMNS)
    ed, et = (hand.column(c).astype(float) for c in AUDIT_COLUMNS)
    ok = np.isfinite(od) & np.isfinite(ot) & np.isfinite(ed) & np.isfinite(et)
    if not ok.any():
        return None
    init = rho * ledger_initial_j(master) + ledger_initial_j(hand)
    initial = np.full(t.shape, init)
    if controller is not None and len(controller.t_s):
        c0 = ledger_initial_j(controller, "store_j")
        initial += np.where(t >= controller.t_s[0], c0, 0.0)
        init += c0
    margin = audit_margin_j(initial, rho, ot, od, et, ed)[ok]
    fod, fot = (float(master.column(c)[np.isfinite(master.column(c))][-1]) for c in AUDIT_COLUMNS)
    fed, fet = float(ed[ok][-1]), float(et[ok][-1])

    def net_out(rec: Recording) -> float:
        if not (rec.has("port_out_j") and rec.has("port_in_j")):
            return math.nan
        return float(rec.column("port_out_j")[-1] - rec.column("port_in_j")[-1])

    return PortAudit(t[ok], margin, float(init), rho, fod, fot, fed, fet,
                     net_out(master) - (fod - fot), net_out(hand) - (fed - fet))


def format_audit(a: PortAudit | None) -> str:
    """One line: the verdict, the lowest margin and the ports' totals."""
    if a is None:
        return ("physical energy audit: none (needs the virtual operator and the simulated "
                "hand: their recordings carry the work done at each port)")
    verdict = ("passive" if a.passive else
               f"ENERGY CREATED: {a.generated_j:.4f} J more delivered than the tanks held and "
               f"the ports took, at {a.min_at_s:.1f} s")
    return (f"physical energy audit (simulated operator and object): {verdict}; lowest margin "
            f"{a.min_margin_j:.3f} J at {a.min_at_s:.1f} s of {a.initial_j:.2f} J initial; "
            f"operator port {a.operator_taken_j:.2f} J taken, {a.operator_delivered_j:.2f} J "
            f"delivered; object {a.environment_delivered_j:.2f} J delivered, "
            f"{a.environment_taken_j:.2f} J taken; the ledgers' net out over the physics' "
            f"{a.ledger_gap_operator_j:+.2f} J (operator), {a.ledger_gap_environment_j:+.2f} J "
            "(object)")
