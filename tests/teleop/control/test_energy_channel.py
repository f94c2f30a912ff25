"""Monotone energy totals: loss, duplication and reordering can only lose energy."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from teleop.control.energy_channel import (
    EnergyLedger,
    TotalReceiver,
    energy_balance,
    receive_total,
)


@settings(max_examples=200, deadline=None)
@given(quanta=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=40),
       fate=st.lists(st.tuples(st.integers(0, 2), st.integers(0, 10)), min_size=40,
                     max_size=40))
def test_receiver_credits_at_most_what_was_sent(quanta: list[float],
                                                fate: list[tuple[int, int]]) -> None:
    """Each message is lost (0), delivered once (1) or twice (2), with a random extra delay."""
    totals = []
    acc = 0.0
    for q in quanta:
        acc += q
        totals.append(acc)
    arrivals = []
    for i, tot in enumerate(totals):
        copies, delay = fate[i]
        arrivals += [(i + delay, j, tot) for j in range(copies)]
    arrivals.sort()
    rx = TotalReceiver()
    credited = 0.0
    for _, _, tot in arrivals:
        rx, inc = receive_total(rx, tot)
        assert inc >= 0.0
        credited += inc
        # at any time the credit equals the largest total seen: never more than was sent
        assert math.isclose(credited, rx.seen_j, rel_tol=1e-12, abs_tol=1e-12)
        assert credited <= totals[-1] + 1e-12
    delivered = [tot for _, _, tot in arrivals]
    assert math.isclose(credited, max(delivered, default=0.0), abs_tol=1e-12)


def test_duplicate_and_stale_totals_add_nothing() -> None:
    rx, inc = receive_total(TotalReceiver(), 0.5)
    assert inc == 0.5
    for stale in (0.5, 0.4, 0.0, -3.0, math.nan, math.inf, None):
        rx, inc = receive_total(rx, stale)
        assert inc == 0.0
    assert rx.seen_j == 0.5


def test_energy_balance_flags_created_energy_and_negative_tank() -> None:
    good = EnergyLedger(initial_j=1.0, tank_j=0.5, port_in_j=0.2, port_out_j=0.5, sent_j=0.2)
    ctl = EnergyLedger(tank_j=0.2, received_j=0.2)
    assert energy_balance((good, ctl)).ok
    forged = EnergyLedger(tank_j=1.2, received_j=1.2)  # credited more than anybody sent
    rep = energy_balance((good, forged))
    assert not rep.ok and "links created" in rep.reason
    over = EnergyLedger(initial_j=1.0, tank_j=-0.5, port_out_j=1.5)
    rep = energy_balance((over,))
    assert not rep.ok and rep.margin_j < 0
    bad_books = EnergyLedger(initial_j=1.0, tank_j=2.0)
    assert "does not balance" in energy_balance((bad_books,)).reason
    assert not energy_balance((EnergyLedger(tank_j=math.nan),)).ok
