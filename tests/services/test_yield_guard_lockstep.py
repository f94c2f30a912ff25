"""The yielding- and unseen-contact guards and the tactile gain cross-check on the simulated
hand, lockstep, judged by the physical audit.

A cylinder that crushes at 5 N under each pad (``hand.sim.object.yield_force_n``) and tactile
cells reading a third of the true force (``hand.sim.tactile_gain``): the first grasp dents the
object for good, so every joule the pads put in stays there.  The hand port's bound is that
the object receives no more than the hand's tank has paid (its ledger's net charge); the
object-port work comes from the simulator's own audit, never from the controller.
Cells that read nothing at all (``tactile_gain = 0``: dead, or a contact off the pads) are the
unseen-contact guard's case (:mod:`teleop.control.stall_guard`); cells reading low on a contact
that neither yields flat nor goes unseen (a work-hardening skin) the gain cross-check's
(:mod:`teleop.control.gain_check`) and, once the contact ends, the yield guard's set check.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from teleop.analysis.sweep_objects import with_object
from teleop.config import load_config
from teleop.control import gain_check, two_layer_hand
from tests.job_pool import JobPool
from tests.services.lockstep_grasps import peaks_of
from tests.services.yield_grasp import first_grasp as grasp_run
from tests.teleop.control.test_set_charge import credit_all

CRUSH = ("hand.sim.object.yield_force_n=5", "hand.sim.tactile_gain=0.333")
DEAD = ("hand.sim.object.yield_force_n=5", "hand.sim.tactile_gain=0")
GAINS = (0.001, 0.01, 0.03, 0.1)
HARDENING = ("hand.sim.object.yield_force_n=5", "hand.sim.object.yield_hardening_n_per_m=2000",
             "hand.sim.tactile_gain=0.333")
HIGH = (*HARDENING[:2], "hand.sim.tactile_gain=3")
DISTAL_LOW = ("hand.sim.object.yield_force_n=5", "hand.sim.distal_tactile_gain=0.1")
GAIN_CHECK_OFF = "controller.tactile.gain_check_window_s=0"
GUARD_OFF = "controller.tactile.yield_stiffness_ratio=0"
SET_CHECK = "controller.tactile.yield_set_check=true"  # the default, said where it matters
SET_OFF = "controller.tactile.yield_set_check=false"
CREDIT_OFF = "controller.tactile.yield_credit=false"  # the default is on
YIELD_OFF = (*CRUSH, GUARD_OFF)

#: every grasp this module judges (override tuples), run together on two processes
GRASPS = (CRUSH, YIELD_OFF, (*YIELD_OFF, GAIN_CHECK_OFF), DEAD,
          (*DEAD, "controller.tactile.stall_window_rad=0"),
          *(("hand.sim.tactile_gain=0", f"master.virtual.style={s}") for s in ("soft", "hard")),
          *(("hand.sim.object.yield_force_n=5", f"hand.sim.tactile_gain={g}") for g in GAINS),
          HARDENING, (*HARDENING, GAIN_CHECK_OFF), (*HARDENING, GUARD_OFF),
          (*HARDENING, GUARD_OFF, GAIN_CHECK_OFF), (*HARDENING, SET_CHECK),
          (*HARDENING, SET_CHECK, GAIN_CHECK_OFF), (*HARDENING, SET_OFF, GAIN_CHECK_OFF), HIGH,
          DISTAL_LOW)


@pytest.fixture(scope="module")
def pool() -> Iterator[JobPool]:
    with JobPool({o: (grasp_run, o) for o in GRASPS}) as p:
        yield p


@pytest.fixture
def first_grasp(pool: JobPool):
    """``first_grasp(*overrides)``: the grasp's figures (``yield_grasp.first_grasp``), from
    the module's pool."""
    return lambda *overrides: pool.result(tuple(overrides))


@pytest.mark.slow
def test_cells_reading_low_on_a_crushing_object_raise_the_alarm_and_the_tank_pays(
        first_grasp) -> None:
    obj, paid, flagged, unseen, _ = first_grasp(*CRUSH)
    assert obj > 0.1  # the pads did crush it
    assert flagged >= 1 and unseen == 0  # the cells see the contact, they read it low
    assert paid >= obj


@pytest.mark.slow
def test_without_the_guard_the_tank_pays_less_than_the_object_took(first_grasp) -> None:
    """The mutant kept as a test: the guard off (and the gain cross-check, which would
    catch it too: next test), the same grasp is charged a fraction of the work the object
    really took (the bound broken, silently)."""
    obj, paid, flagged, _, low = first_grasp(*YIELD_OFF, GAIN_CHECK_OFF)
    assert flagged == 0 and low == 0
    assert np.isfinite(paid) and paid < 0.5 * obj


@pytest.mark.slow
def test_with_the_yield_guard_off_the_gain_check_still_catches_the_crushing_grasp(
        first_grasp) -> None:
    """The two checks overlap: the crushing grasp is held still at its end, and the gain
    cross-check finds its cells reading a third (measured 2026-11-26: 0.52 J paid for
    0.26 J)."""
    obj, paid, flagged, _, low = first_grasp(*YIELD_OFF)
    assert flagged == 0 and low >= 1
    assert paid >= obj


@pytest.mark.slow
def test_dead_cells_on_a_crushing_object_raise_the_alarm_and_the_tank_pays(
        first_grasp) -> None:
    """Cells reading nothing: the fingers stall on the cylinder with silent cells, the
    unseen-contact guard flags them and charges their further advance at the servo's torque
    (measured 2026-11-29: object 0.30 J, tank paid 15.2 J, 3 fingers)."""
    obj, paid, _, unseen, _ = first_grasp(*DEAD)
    assert obj > 0.1
    assert unseen >= 1
    assert paid >= obj


@pytest.mark.slow
def test_without_the_stall_guard_dead_cells_are_charged_nothing(first_grasp) -> None:
    """The mutant kept as a test: the guard off, the crushing grasp costs the tank nothing."""
    obj, paid, _, unseen, _ = first_grasp(*DEAD, "controller.tactile.stall_window_rad=0")
    assert unseen == 0
    assert obj > 0.1 and paid < 0.5 * obj


@pytest.mark.slow
@pytest.mark.parametrize("style", ["soft", "hard"])
def test_dead_cells_on_an_elastic_object_raise_the_alarm(first_grasp, style: str) -> None:
    """An elastic cylinder, every operator: the alarm comes whatever the object does (the
    operator feels nothing and squeezes on; the tank pays the servo's worst case)."""
    obj, paid, flagged, unseen, _ = first_grasp("hand.sim.tactile_gain=0",
                                             f"master.virtual.style={style}")
    assert unseen >= 1 and flagged == 0
    assert paid >= obj


@pytest.mark.slow
@pytest.mark.parametrize("gain", GAINS)
def test_at_any_gain_one_guard_or_the_other_raises_the_alarm_and_the_tank_pays(
        first_grasp, gain: float) -> None:
    """The tactile calibration swept from nothing to a tenth on the crushing cylinder: cells
    below their noise floor leave the contact unseen (the stall guard flags it), cells that
    see it read the yield's flat chords (the yield guard); either way the tank pays at
    least what the object took (measured 2026-11-26 at gains 0-0.2: 9.0-14.5 J paid for
    0.29-0.30 J)."""
    obj, paid, flagged, unseen, _ = first_grasp("hand.sim.object.yield_force_n=5",
                                             f"hand.sim.tactile_gain={gain}")
    assert obj > 0.1
    assert flagged + unseen >= 1
    assert paid >= obj


@pytest.mark.slow
def test_a_work_hardening_object_with_cells_reading_low_raises_the_alarm_and_the_tank_pays(
        first_grasp) -> None:
    """A skin whose yield level rises 2 N per mm of dent keeps its chords steeper than a
    fifth of the elastic ones, so the yield guard's chords see nothing while it is pressed;
    the gain cross-check (:mod:`teleop.control.gain_check`) finds the held grasp's cells
    reading a third of the moment the servo's load implies, flags the fingers and
    re-charges their work at the measured ratio: the tank pays at least the plastic work
    (docs/controllers.md's table).  The yield guard's set check (on by default) finds
    the dent when the grasp opens, and charged at the ratio the gain check
    measured in the grasp, not flagged."""
    obj, paid, flagged, unseen, low = first_grasp(*HARDENING)
    assert obj > 0.05  # the pads did dent it
    assert flagged == 0 and unseen == 0 and low >= 1
    assert paid >= obj
    obj, paid, flagged, unseen, low = first_grasp(*HARDENING, SET_CHECK)
    assert flagged == 0 and low >= 1 and paid >= obj


@pytest.mark.slow
def test_with_the_yield_guard_off_the_gain_check_alone_catches_the_hardening_object(
        first_grasp) -> None:
    """The yield guard off (its chords and the set check): the gain cross-check alone
    still makes the tank pay at least the plastic work (measured 2026-11-29: 0.48 J for
    0.12 J)."""
    obj, paid, flagged, unseen, low = first_grasp(*HARDENING, GUARD_OFF)
    assert flagged == 0 and unseen == 0 and low >= 1
    assert paid >= obj


@pytest.mark.slow
def test_with_the_gain_check_off_the_set_check_alone_catches_the_hardening_object(
        first_grasp) -> None:
    """The gain cross-check off, the set check on (``yield_set_check``, the default): the
    dent the grasp leaves is found when the contact ends, no window measured the cells, so
    the fingers are flagged and their winding over it re-charged at the servo's torque
    (measured 2026-11-29: 12.2 J for 0.12 J, two fingers flagged)."""
    obj, paid, flagged, unseen, low = first_grasp(*HARDENING, SET_CHECK, GAIN_CHECK_OFF)
    assert low == 0 and unseen == 0 and flagged >= 1
    assert paid >= obj


@pytest.mark.slow
def test_without_either_check_the_hardening_object_is_under_paid(first_grasp) -> None:
    """The mutant kept as a test (the gain check off, and the yield guard off or without its
    set check): nothing is flagged and the tank pays about 60 % of the plastic work
    (measured 2026-11-29: 0.070 J for 0.116 J), the gap the checks close."""
    for overrides in ((*HARDENING, GUARD_OFF, GAIN_CHECK_OFF),
                      (*HARDENING, SET_OFF, GAIN_CHECK_OFF)):
        obj, paid, flagged, unseen, low = first_grasp(*overrides)
        assert flagged == 0 and unseen == 0 and low == 0
        assert 0.0 < paid < 0.75 * obj


@pytest.mark.slow
def test_cells_reading_high_on_the_hardening_object_over_pay(first_grasp) -> None:
    """The other side of the calibration assumption: cells reading 3x the force.  Nothing is
    flagged (the check looks for cells reading low), the tank pays more than the object took
    (the estimate is scaled up: conservative), and the operator, feeling the grasp 3x
    harder, dents the object less."""
    obj, paid, flagged, unseen, low = first_grasp(*HIGH)
    assert low == 0 and unseen == 0
    assert paid >= obj > 0.0


@pytest.mark.slow
def test_the_gain_checks_measurement_alone_makes_the_set_charge_pay(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The set check's charge for a finger the gain cross-check measured
    (:func:`teleop.control.gain_check.set_charge_j`), judged alone: the check's own verdict
    switched off (``LOW_WINDOWS`` beyond reach: no finger flagged low, nothing scaled), its
    windows still measuring the cells.  On the hardening skin with cells reading a third,
    the dent found when the grasp opens is charged ``(r - m)`` of the cells' work and the
    tank pays at least what the object kept; the same with that charge dropped (the mutant)
    pays about 60 % of it, as with the set check off."""
    monkeypatch.setattr(gain_check, "LOW_WINDOWS", 10**6)
    obj, paid, flagged, unseen, low = grasp_run(*HARDENING, SET_CHECK)
    assert obj > 0.05 and low == 0 and unseen == 0 and flagged == 0
    assert paid >= obj
    monkeypatch.setattr(two_layer_hand, "set_charge_j", lambda *_a: 0.0)
    obj, paid, flagged, _, _ = grasp_run(*HARDENING, SET_CHECK)
    assert flagged == 0 and 0.0 < paid < 0.75 * obj


@pytest.mark.slow
def test_a_set_on_cells_the_gain_check_measured_does_not_starve_later_grasps(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The hard operator on the crushable cylinder with true cells, the set check on: its
    first grasp leaves a 9 mm set on a finger the chords do not flag.  Charged at the ratio
    the gain check measured in that grasp (~1.15: next to nothing), the later grasps are as
    firm as the first; charged the servo's worst case over the contact's winding instead
    (the mutant: every set flagged, as before the measured charge; ~6 J), the tank does
    not recover and the second grasp is a third softer (measured 2026-11-29: 3,337 then
    2,122)."""
    cfg = with_object(load_config(None, ["master.virtual.style=hard", SET_CHECK, CREDIT_OFF]),
                      "crushable-cylinder")

    built = peaks_of(cfg, 15.0)
    assert len(built) >= 3 and min(built) >= 0.99 * built[0]
    monkeypatch.setattr(two_layer_hand, "set_charge_j", lambda *_a: None)
    worst = peaks_of(cfg, 15.0)
    assert worst[0] == pytest.approx(built[0], rel=1e-3) and worst[1] < 0.8 * worst[0]


@pytest.mark.slow
def test_the_hard_operators_crushable_grasps_hold_up_under_a_small_delay() -> None:
    """Issue 13's floor (every grasp at least 90 % of the first's peak pressure) for the hard
    operator on the crushable cylinder with 2 ms on both links, 30 s (seven grasps).  The
    first grasp dents the cylinder and the chords flag the fingers; the flag's re-charge at
    the servo's worst case (several joules) would drain the hand's tank under the hard
    squeezes.  Once the gain cross-check has measured the flagged fingers' cells in the grasp
    (``r`` about 1.15), ``yield_credit`` gives back what was paid beyond ``r`` times the
    contact's estimated work (measured 2026-11-29, 60 s: 3,326-3,342, the tank ending 16.7 J).
    The mutant kept as a test: the credit off, the grasps fall (2,835 to 2,286 in 60 s, the
    tank ending 1.95 J; a strict xfail while the credit was off by default)."""
    peaks = _hard_crushable_peaks()
    assert len(peaks) >= 6
    assert min(peaks) >= 0.9 * peaks[0], [round(p) for p in peaks]
    without = _hard_crushable_peaks(CREDIT_OFF)
    assert len(without) >= 6 and min(without) < 0.9 * without[0], [round(p) for p in without]


def _hard_crushable_peaks(*overrides: str) -> list[float]:
    cfg = with_object(load_config(None, [
        "master.virtual.style=hard", "links.controller_hand.delay_s=0.002",
        "links.master_controller.delay_s=0.002", *overrides]), "crushable-cylinder")
    return peaks_of(cfg, 30.0)


@pytest.mark.slow
def test_with_the_credit_cells_reading_low_still_pay_what_the_object_took(
        first_grasp, monkeypatch: pytest.MonkeyPatch) -> None:
    """The credit rests on the gain the cross-check measured: cells reading a third on the
    crushing and on the hardening skin, their flags' worst case credited down to ``r``
    times the cells' work, still pay at least what the object kept (the physical audit).
    Judged alone too, the gain check's own verdict switched off (``LOW_WINDOWS`` out of
    reach: nothing scaled) on the crushing skin; the mutant (every worst-case joule
    credited once a window measured the cells) then pays less than the skin kept."""
    for overrides in (CRUSH, HARDENING):
        obj, paid, _, _, _ = first_grasp(*overrides)
        assert obj > 0.05 and paid >= obj, (overrides, obj, paid)
    monkeypatch.setattr(gain_check, "LOW_WINDOWS", 10**6)
    obj, paid, _, _, low = grasp_run(*CRUSH)
    assert low == 0 and obj > 0.05 and paid >= obj
    monkeypatch.setattr(two_layer_hand, "worst_case_credit_j", credit_all)
    obj, paid, _, _, _ = grasp_run(*CRUSH)
    assert paid < obj


@pytest.mark.slow
def test_with_the_credit_cells_reading_low_on_the_distal_pad_alone_still_pay(first_grasp
                                                                             ) -> None:
    """The credit's stated blind spot: ``r`` is measured on the moment both pads share, so
    distal cells reading low while the proximal ones read true could make ``r`` times the
    cells' work fall short of what the object took.  On the crushing skin with the distal
    cells reading a tenth (``hand.sim.distal_tactile_gain``) the gain cross-check still
    flags the fingers (``cells_low``) and the tank pays more than the object kept (measured
    2026-11-29: 0.87 J for 0.063 J; 8.5 J with the credit off).  Not a mutant catcher (every
    worst-case joule credited still pays 0.37 J here): a check that the blind spot stays
    closed on the simulated hand."""
    obj, paid, flagged, _, low = first_grasp(*DISTAL_LOW)
    assert obj > 0.03 and flagged >= 1 and low >= 1
    assert paid >= obj
