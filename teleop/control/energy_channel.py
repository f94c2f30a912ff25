"""Energy sent as monotone cumulative totals, and the energy-balance checker.

Every message carries its sender's cumulative total of energy sent on that link
(``Header.energy_total_j``).  The receiver remembers the largest total it has seen and credits
only the increase: a lost message loses its quantum (the next one carries it, or it is gone
for good if the sender has since been credited nothing more), a duplicated or reordered
(older, smaller) total adds nothing.  So the channel can lose energy, never create it:
received(k) <= sent(k) at every sample, whatever the channel does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from teleop.frozen import fast_init


@fast_init
@dataclass(frozen=True, slots=True)
class TotalReceiver:
    """The largest cumulative total seen so far on one incoming link."""

    seen_j: float = 0.0


def receive_total(rx: TotalReceiver, total_j: float | None) -> tuple[TotalReceiver, float]:
    """Credit only the increase of the running total; return the new receiver and the increment.

    ``None`` (nothing received), non-finite and negative totals credit nothing.
    """
    if total_j is None or not math.isfinite(total_j) or total_j <= rx.seen_j:
        return rx, 0.0
    return TotalReceiver(seen_j=total_j), total_j - rx.seen_j


@fast_init
@dataclass(frozen=True, slots=True)
class EnergyLedger:
    """Cumulative energy accounts of one side (all non-negative, all monotone except tank_j).

    ``port_in_j``: energy taken from the physical port (the operator or environment did work
    on the device, or the hand's servo dissipation credited by set-position modulation);
    ``port_out_j``: energy delivered to the port; ``sent_j``/``received_j``: energy put on /
    credited from the links; ``dissipated_j``: surplus thrown away (tank upper limit);
    ``initial_j``: the tank's initial content.
    """

    initial_j: float = 0.0
    tank_j: float = 0.0
    port_in_j: float = 0.0
    port_out_j: float = 0.0
    sent_j: float = 0.0
    received_j: float = 0.0
    dissipated_j: float = 0.0


def book(led: EnergyLedger, tank_j: float, port_in_j: float = 0.0, port_out_j: float = 0.0,
         sent_j: float = 0.0, received_j: float = 0.0,
         dissipated_j: float = 0.0) -> EnergyLedger:
    """``led`` after one sample: the tank now at ``tank_j``, each cumulative account raised by
    this sample's amount (``initial_j`` kept)."""
    return EnergyLedger(initial_j=led.initial_j, tank_j=tank_j,
                        port_in_j=led.port_in_j + port_in_j,
                        port_out_j=led.port_out_j + port_out_j, sent_j=led.sent_j + sent_j,
                        received_j=led.received_j + received_j,
                        dissipated_j=led.dissipated_j + dissipated_j)


def ledger_residual_j(led: EnergyLedger) -> float:
    """initial + in + received - out - sent - dissipated - tank (zero for exact bookkeeping)."""
    return (led.initial_j + led.port_in_j + led.received_j - led.port_out_j - led.sent_j
            - led.dissipated_j - led.tank_j)


@dataclass(frozen=True, slots=True)
class BalanceReport:
    """The result of :func:`energy_balance`."""

    ok: bool
    delivered_j: float  # energy delivered at both ports
    bound_j: float  # initial tank energy + energy taken from both ports
    margin_j: float  # bound - delivered (>= 0 when passive)
    created_by_links_j: float  # received - sent over all links (must be <= 0)
    bookkeeping_error_j: float  # largest |ledger residual| of any side
    reason: str = ""


def scaled(led: EnergyLedger, w: float) -> EnergyLedger:
    """Every account of ``led`` times ``w`` (master joules -> hand joules under scaling)."""
    return EnergyLedger(*(w * getattr(led, f) for f in led.__slots__))  # type: ignore[attr-defined]


def energy_balance(sides: tuple[EnergyLedger, ...], tol_j: float = 1e-9,
                   weights: tuple[float, ...] | None = None) -> BalanceReport:
    """Check the system-wide passivity inequality over the ledgers of every side.

    With the ledgers of master, controller and hand (any order): energy delivered at the
    ports must not exceed the initial tank energy plus the energy taken from the ports, the
    links must not have created energy (total received <= total sent), every ledger must
    balance, no tank may be negative, and nothing may be NaN.  With power scaling
    (``controller.tank.energy_scale`` = rho != 1) pass ``weights=(rho, 1, 1)`` for
    (master, controller, hand): the inequality then holds in hand-side joules.
    """
    if weights is not None:
        sides = tuple(scaled(s, w) for s, w in zip(sides, weights, strict=True))
    delivered = sum(s.port_out_j for s in sides)
    bound = sum(s.initial_j + s.port_in_j for s in sides)
    created = sum(s.received_j for s in sides) - sum(s.sent_j for s in sides)
    resid = max((abs(ledger_residual_j(s)) for s in sides), default=0.0)
    values = [getattr(s, f) for s in sides for f in s.__slots__]  # type: ignore[attr-defined]
    reason = ""
    if not all(math.isfinite(v) for v in values):
        reason = "non-finite energy"
    elif delivered > bound + tol_j:
        reason = f"delivered {delivered:.6g} J exceeds bound {bound:.6g} J"
    elif created > tol_j:
        reason = f"links created {created:.6g} J"
    elif any(s.tank_j < -tol_j for s in sides):
        reason = "negative tank"
    elif resid > tol_j * max(1.0, bound):
        reason = f"ledger does not balance ({resid:.3g} J)"
    return BalanceReport(ok=not reason, delivered_j=delivered, bound_j=bound,
                         margin_j=bound - delivered, created_by_links_j=created,
                         bookkeeping_error_j=resid, reason=reason)
