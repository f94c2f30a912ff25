"""What a set found at a contact's end costs a finger whose cells the gain cross-check measured
in that contact (:func:`teleop.control.gain_check.set_charge_j`), and its wiring into the
two-layer hand.

The grasps are :func:`tests.teleop.control.test_gain_check.hold`'s: a contact moment the test
chooses, the servo's load the statics need for it (noisy), the cells reading ``g`` of it.  The
safety property: the charge covers what the tank's margin leaves unpaid of the true work,
``(1 - m g)`` of ``W_cells / g``.  The kept mutants are at the end.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import replace

import pytest

from teleop.control import gain_check, two_layer_hand
from teleop.control.gain_check import UNCHECKED, GainTrack, set_charge_j, step_gain
from teleop.control.two_layer_hand import worst_case_credit_j
from teleop.control.yield_guard import SET_FOUND
from teleop.messages import FingerState
from tests.mutants import fails
from tests.teleop.control.test_gain_check import DT_S, MODEL, hold, load_for, pressing_sample

M = MODEL.force_margin
INTO_J = 0.004  # the cells' estimated work into the object per sample


def _contact(gain: float, seconds: float = 2.0, tau_nm: float = 0.8,
             track: GainTrack = UNCHECKED) -> GainTrack:
    tracks, _ = hold(tau_nm, gain, seconds, into_j=INTO_J, track=track)
    return tracks[-1]


def _released(track: GainTrack) -> GainTrack:
    """The sample in which the cells stop reading: the contact's figures end."""
    f = FingerState(0.2, 0.5, 1.0, load_for(0.0), (), ())
    return step_gain(track, f, 0.0, 0.0, DT_S, MODEL)[0]


def test_a_measured_contact_keeps_its_work_and_a_ratio_that_bounds_the_gain() -> None:
    for g in (0.2, 1 / 3, 0.8, 1.0):
        t = _contact(g)
        assert t.contact_into_j == pytest.approx(INTO_J * round(2.0 / DT_S))
        assert t.contact_ratio >= 1.0 / g  # every resolved window's upper bound: >= 1/g
        assert t.contact_ratio <= (0.8 + MODEL.gain_check_tolerance_nm + 0.01) / (g * 0.8)


def test_the_charge_covers_what_the_margin_leaves_unpaid() -> None:
    """The object took ``W / g`` for the cells' ``W``; the tank paid ``m W``."""
    for g in (0.1, 0.2, 1 / 3, 0.6, 0.8):
        t = _contact(g)
        shortfall = t.contact_into_j * (1.0 / g - M)
        charge = set_charge_j(t, 0.0, M)
        assert charge is not None and charge >= shortfall > 0.0


def test_cells_reading_true_cost_a_set_little() -> None:
    """True cells on a 2 N m grasp: the ratio is the tolerance's share above 1 (1.075), under
    the margin: nothing is charged (the worst case would be the servo's torque times the
    whole contact's winding)."""
    t = _contact(1.0, tau_nm=2.0)
    assert set_charge_j(t, 0.01, M) == 0.0


def test_a_contact_no_window_measured_falls_to_the_worst_case() -> None:
    brief = _contact(1 / 3, seconds=0.1)  # under one window
    assert brief.contact_into_j > 0.0 and set_charge_j(brief, 0.0, M) is None


def test_the_next_contact_earns_its_own_ratio() -> None:
    """A measured contact ends; the next one is too brief for a window: its set is the worst
    case's, not charged at the last contact's ratio."""
    t = _released(_contact(1.0, tau_nm=2.0))
    assert t.contact_ratio == 0.0 and t.contact_into_j == 0.0
    assert set_charge_j(_contact(1 / 3, seconds=0.1, track=t), 0.0, M) is None


def test_the_check_off_measures_nothing() -> None:
    off = replace(MODEL, gain_check_window_s=0.0)
    tracks, _ = hold(0.8, 1 / 3, 2.0, into_j=INTO_J, model=off)
    assert set_charge_j(tracks[-1], 0.0, M) is None


# ------------------------------------------------------------------------ the wiring
def _one_sample(gains: tuple[GainTrack, ...], monkeypatch: pytest.MonkeyPatch
                ) -> tuple[float, int]:
    """:func:`pressing_sample` with finger 0's contact ending in a set in its second sample
    (the yield guard's step patched to find one), its gain tracks ``gains`` before it:
    ``(what the tank paid, fingers flagged yielding)``."""
    built = two_layer_hand.step_yield
    calls = iter(range(6))

    def step_yield(*a: object) -> object:
        return SET_FOUND if next(calls) == 3 else built(*a)  # type: ignore[arg-type]

    monkeypatch.setattr(two_layer_hand, "step_yield", step_yield)
    paid, out = pressing_sample(gains)
    monkeypatch.setattr(two_layer_hand, "step_yield", built)
    return paid, out.yielding


def test_a_measured_finger_pays_the_set_charge_and_is_not_flagged(
        monkeypatch: pytest.MonkeyPatch) -> None:
    true = GainTrack(contact_into_j=0.5, contact_ratio=1.1)
    low = GainTrack(contact_into_j=0.5, contact_ratio=3.0)
    plain, flags = _one_sample((true, UNCHECKED, UNCHECKED), monkeypatch)
    assert flags == 0
    paid, flags = _one_sample((low, UNCHECKED, UNCHECKED), monkeypatch)
    assert flags == 0
    # (3 - m) of the contact's 0.5 J, this sample's share of it aside
    assert paid - plain == pytest.approx((3.0 - M) * 0.5, rel=0.02)


def test_an_unmeasured_finger_is_flagged(monkeypatch: pytest.MonkeyPatch) -> None:
    _, flags = _one_sample((UNCHECKED,) * 3, monkeypatch)
    assert flags == 1


# ------------------------------------------------------------------------- kept mutants
def _margin_flipped(track: GainTrack, into_j: float, margin: float) -> float | None:
    if track.contact_ratio <= 0.0:
        return None
    return max(margin - track.contact_ratio, 0.0) * (track.contact_into_j + into_j)


def _never_worst_case(track: GainTrack, into_j: float, margin: float) -> float | None:
    return max(track.contact_ratio - margin, 0.0) * (track.contact_into_j + into_j)


CHECKS: dict[str, Callable[[], None]] = {
    "covers": test_the_charge_covers_what_the_margin_leaves_unpaid,
    "brief": test_a_contact_no_window_measured_falls_to_the_worst_case,
    "next": test_the_next_contact_earns_its_own_ratio,
}


@pytest.mark.parametrize("mutant", [_margin_flipped, _never_worst_case],
                         ids=["margin flipped", "never the worst case"])
def test_a_broken_charge_fails_a_check(mutant: Callable[..., float | None],
                                       monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(gain_check, "set_charge_j", mutant)
    monkeypatch.setattr(sys.modules[__name__], "set_charge_j", mutant)
    assert any(fails(c) for c in CHECKS.values())


def test_contact_figures_kept_past_the_release_fail_a_check(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The mutant: the contact's figures carried over when the cells stop reading."""
    built = gain_check.step_gain

    def sticky(prev: GainTrack, f: FingerState, cells_nm: float, into_j: float,
               dt_s: float, model: object) -> tuple[GainTrack, float]:
        t, r = built(prev, f, cells_nm, into_j, dt_s, model)  # type: ignore[arg-type]
        if cells_nm <= 0.0:
            t = replace(t, contact_into_j=prev.contact_into_j,
                        contact_ratio=prev.contact_ratio)
        return t, r

    monkeypatch.setattr(sys.modules[__name__], "step_gain", sticky)
    assert fails(test_the_next_contact_earns_its_own_ratio)


def test_the_checks_pass_as_built() -> None:
    assert not any(fails(c) for c in CHECKS.values())


# ------------------------------------------- the worst case credited back (yield_credit)
def _measured(ratio: float, into_j: float) -> GainTrack:
    return GainTrack(contact_into_j=into_j, contact_ratio=ratio)


def test_no_credit_before_a_window_measures_the_cells() -> None:
    credited, delta = worst_case_credit_j((5.0, 5.0, 0.0), (0.0,) * 3,
                                          (UNCHECKED, _measured(0.0, 1.0), UNCHECKED))
    assert credited == (0.0, 0.0, 0.0) and delta == 0.0


def test_the_credit_keeps_r_times_the_contacts_work() -> None:
    """Paid 5 J at the worst case for a contact whose cells estimate 1 J into the object and
    read at least 1/1.2 of the force: 1.2 J is kept, 3.8 J goes back; a finger that paid
    less than that keeps all of it."""
    credited, delta = worst_case_credit_j((5.0, 1.0, 0.0), (0.0,) * 3,
                                          (_measured(1.2, 1.0), _measured(1.2, 1.0), UNCHECKED))
    assert credited == pytest.approx((3.8, 0.0, 0.0)) and delta == pytest.approx(3.8)


def test_a_credit_the_contact_outgrows_is_charged_back() -> None:
    """The contact goes on: its estimated work and measured ratio grow, what it must keep
    grows with them, and the credit given earlier is taken back as far as needed."""
    credited, _ = worst_case_credit_j((5.0, 0.0, 0.0), (0.0,) * 3, (_measured(1.2, 1.0),) * 3)
    later, delta = worst_case_credit_j((5.0, 0.0, 0.0), credited, (_measured(3.0, 1.5),) * 3)
    assert later == pytest.approx((0.5, 0.0, 0.0)) and delta == pytest.approx(0.5 - 3.8)


def credit_all(worst_j: tuple[float, ...], credited_j: tuple[float, ...],
                gains: tuple[GainTrack, ...]) -> tuple[tuple[float, ...], float]:
    out = tuple(w if g.contact_ratio > 0 else 0.0 for w, g in zip(worst_j, gains, strict=False))
    return out, sum(out) - sum(credited_j)


def _never_charged_back(worst_j: tuple[float, ...], credited_j: tuple[float, ...],
                        gains: tuple[GainTrack, ...]) -> tuple[tuple[float, ...], float]:
    out, _ = two_layer_hand.worst_case_credit_j(worst_j, credited_j, gains)  # type: ignore[arg-type]
    out = tuple(max(a, b) for a, b in zip(out, credited_j, strict=False))
    return out, sum(out) - sum(credited_j)


CREDIT_CHECKS: dict[str, Callable[[], None]] = {
    "keeps": test_the_credit_keeps_r_times_the_contacts_work,
    "back": test_a_credit_the_contact_outgrows_is_charged_back,
}


@pytest.mark.parametrize("mutant", [credit_all, _never_charged_back],
                         ids=["everything credited", "never charged back"])
def test_a_broken_credit_fails_a_check(mutant: Callable[..., object],
                                       monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sys.modules[__name__], "worst_case_credit_j", mutant)
    assert any(fails(c) for c in CREDIT_CHECKS.values())


def test_the_credit_checks_pass_as_built() -> None:
    assert not any(fails(c) for c in CREDIT_CHECKS.values())
