"""The tactile gain cross-check's step on its own: held grasps whose cells read the contact
moment the servo's load implies, or a fraction of it.

The trajectories are built from a contact moment ``tau`` the test chooses: the load is what
the finger's statics need for it (``c_L load = tau + k_b (t_p + t_0)``, plus the servo's
friction where the motor creeps), the cells read ``g tau``.  The mutants of the verdict
(:func:`teleop.control.gain_check.reads_low`: comparison flipped, margin ignored) are kept at
the end: each must make one of these checks fail.
"""

from __future__ import annotations

import random
from collections.abc import Callable
from dataclasses import replace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from teleop.config.control import ControllerConfig
from teleop.control import gain_check, two_layer
from teleop.control.gain_check import (
    LOW_WINDOWS,
    UNCHECKED,
    GainTrack,
    check_gains,
    servo_moment_nm,
    step_gain,
)
from teleop.control.interface import HandOutput, control_params
from teleop.control.object_port import PadTrack, TactileModel, kernel
from teleop.messages import FingerState, HandCommand, HandMode, Header
from tests.teleop.control.two_layer_parts import patch_sides

MODEL = TactileModel()
DT_S = 0.025  # the hand's 40 Hz
PROXIMAL_RAD = 0.2


def load_for(tau_nm: float, proximal_rad: float = PROXIMAL_RAD) -> float:
    """The present load that holds a contact moment ``tau_nm`` at ``proximal_rad``."""
    spring = MODEL.base_spring_nm_per_rad * (proximal_rad + MODEL.base_preload_rad)
    return (tau_nm + spring) / MODEL.load_torque_nm_per_unit


def hold(tau_nm: float, gain: float, seconds: float, *, creep_rad_s: float = 0.0,
         friction_nm: float = 0.0, noise: bool = True, proximal_rad: float = PROXIMAL_RAD,
         track: GainTrack = UNCHECKED, into_j: float = 0.0, seed: int = 1,
         model: TactileModel = MODEL) -> tuple[list[GainTrack], float]:
    """Follow the check along a held grasp: the motor creeping at ``creep_rad_s`` (joint
    side), the servo's load reading ``friction_nm`` more than the statics need (its friction
    while creeping), the cells ``gain`` of the moment; the load noisy (3 units, rounded) when
    ``noise``.  Returns the tracks and the total re-charge."""
    rng = random.Random(seed)
    out, recharge = [], 0.0
    for k in range(int(round(seconds / DT_S))):
        load = load_for(tau_nm + friction_nm, proximal_rad)
        if noise:
            load = float(round(load + rng.gauss(0.0, 3.0)))
        f = FingerState(proximal_rad, 0.5, 1.0 + creep_rad_s * k * DT_S, load, (), ())
        track, r = step_gain(track, f, gain * tau_nm, into_j, DT_S, model)
        out.append(track)
        recharge += r
    return out, recharge


def test_cells_that_read_the_servos_moment_are_never_flagged() -> None:
    for tau in (0.05, 0.2, 0.5, 1.5, 3.0):
        track, _ = hold(tau, 1.0, 5.0)
        assert not any(t.low for t in track)


def test_cells_reading_a_third_are_flagged_after_two_held_windows() -> None:
    track, _ = hold(0.6, 1 / 3, 2.0)
    first = next(i for i, t in enumerate(track) if t.low)
    # two windows of 0.2 s (a window is judged at the sample that completes it)
    assert first * DT_S == pytest.approx(LOW_WINDOWS * MODEL.gain_check_window_s, abs=DT_S)
    assert all(t.low for t in track[first:])


def test_the_scale_bounds_the_true_ratio_from_above() -> None:
    """``s`` is the window's upper bound of the moment over the cells': at least 1/g, and
    no more than the tolerance's share above it."""
    for g in (0.1, 1 / 3, 0.6):
        tau = 0.8
        track, _ = hold(tau, g, 2.0)
        s = track[-1].scale
        assert s >= 1.0 / g
        assert s <= (tau + MODEL.gain_check_tolerance_nm + 0.01) / (g * tau)


def test_cells_low_within_their_margin_are_not_flagged() -> None:
    """Cells reading 1/1.25 of a 1 N m moment: below the truth by more than the tolerance
    (0.2 > 0.15 N m), within it once the margin is allowed (1.15 x 0.8 = 0.92 > 0.85)."""
    track, _ = hold(1.0, 0.8, 3.0)
    assert not any(t.low for t in track)


def test_cells_reading_high_are_never_flagged() -> None:
    """Cells reading 3x the force: the tank over-pays (the safe side); nothing to flag."""
    for tau in (0.2, 0.6, 2.0):
        track, _ = hold(tau, 3.0, 3.0)
        assert not any(t.low for t in track)


def test_a_light_touch_is_below_what_the_check_can_tell() -> None:
    """A moment under ``tol / (1 - m g)``: a third-gain reading is not flagged (stated)."""
    tol, m = MODEL.gain_check_tolerance_nm, MODEL.force_margin
    tau = 0.8 * tol / (1.0 - m / 3.0)
    track, _ = hold(tau, 1 / 3, 3.0)
    assert not any(t.low for t in track)


def test_a_creeping_motors_friction_is_not_read_as_force() -> None:
    """The motor winds in at 0.06 rad/s (within the window's stillness): the servo's load
    reads its viscous friction on top of the tendon's pull.  Subtracted at the stated upper
    bound, true cells are not flagged; counted as contact force, they would be."""
    creep = 0.06
    friction = 0.9 * MODEL.gain_check_damping_nm_s_per_rad * creep
    track, _ = hold(0.5, 1.0, 4.0, creep_rad_s=creep, friction_nm=friction)
    assert not any(t.low for t in track)
    blind = TactileModel(gain_check_damping_nm_s_per_rad=0.0)
    track, _ = hold(0.5, 1.0, 4.0, creep_rad_s=creep, friction_nm=friction, model=blind)
    assert any(t.low for t in track)


def test_a_moving_finger_is_not_judged() -> None:
    """Winding in faster than the stillness allows: no window completes, whatever the cells."""
    speed = 2.0 * MODEL.gain_check_still_rad / MODEL.gain_check_window_s
    track, _ = hold(0.8, 0.1, 3.0, creep_rad_s=speed)
    assert not any(t.low for t in track)
    assert all(t.held_s < MODEL.gain_check_window_s for t in track)


def test_a_finger_on_its_open_stop_is_not_judged() -> None:
    """The stop holds an unknown moment: the statics say nothing there."""
    track, _ = hold(0.8, 0.1, 3.0, proximal_rad=0.5 * gain_check.OFF_STOP_RAD)
    assert not any(t.low for t in track)


def test_the_check_off_never_flags() -> None:
    track, _ = hold(0.8, 0.1, 3.0, model=TactileModel(gain_check_window_s=0.0))
    assert not any(t.low for t in track)


def test_the_flag_is_latched_when_the_contact_ends() -> None:
    track, _ = hold(0.6, 1 / 3, 1.0)
    assert track[-1].low
    f = FingerState(PROXIMAL_RAD, 0.5, 1.0, 0.0, (), ())
    after, _ = step_gain(track[-1], f, 0.0, 0.0, DT_S, MODEL)  # the cells see nothing
    assert after.low and after.scale == track[-1].scale


def test_a_flagged_finger_opening_does_not_raise_its_scale_on_unreadable_moments() -> None:
    """Flagged at a third, then the grasp opens: the cells read 0.02 N m, the servo the same
    within its noise, far under the check's tolerance.  Such windows cannot measure a gain
    and leave the scale and the tank alone; taken as ``upper / tau_cells`` they read the
    tolerance as a gain error (8x and more) and re-charged all the finger's work at it (a live
    run, 2026-11-26: the hand's tank from 11 J to -404 J as a flagged finger opened)."""
    flagged, _ = hold(0.6, 1 / 3, 1.0)
    assert flagged[-1].low and 2.0 < flagged[-1].scale < 6.0
    after, recharge = hold(0.02, 1.0, 2.0, track=flagged[-1], into_j=0.001)
    # (the first window still holds the grasp's own samples: a percent at most)
    assert after[-1].scale < 1.02 * flagged[-1].scale
    assert recharge < 0.02 * flagged[-1].into_j + 1e-12
    # still raised by a window it can read: the same cells at a tenth of a real moment
    again, recharge = hold(0.6, 0.1, 1.0, track=flagged[-1], into_j=0.001)
    assert again[-1].scale > 5.0 and recharge > 0.0


def test_a_load_scale_calibrated_high_flags_true_cells_on_the_safe_side() -> None:
    """The check's own assumption broken: the load read as 1.5x the torque it stands for.
    True cells are then flagged (a false alarm) and charged more: over-paid, not under."""
    high = TactileModel(load_torque_nm_per_unit=1.5 * MODEL.load_torque_nm_per_unit)
    track, _ = hold(0.6, 1.0, 2.0, model=high)
    assert track[-1].low and track[-1].scale > 1.0


def test_a_load_scale_calibrated_low_hides_cells_reading_a_third() -> None:
    """The other way (the load read as half the torque): cells reading a third go unflagged,
    the check's coverage is lost (the hardening skin is then under-paid as with the check
    off)."""
    low = TactileModel(load_torque_nm_per_unit=0.5 * MODEL.load_torque_nm_per_unit)
    track, _ = hold(0.6, 1 / 3, 3.0, model=low)
    assert not any(t.low for t in track)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(0.0, 0.01), min_size=1, max_size=120),
       st.floats(0.05, 0.5), st.floats(0.3, 2.0))
def test_the_recharges_bring_every_joule_so_far_to_the_final_scale(
        intos: list[float], gain: float, tau: float) -> None:
    """Whatever the work per sample and whenever the scale rises: the sample charges
    (``s into`` at the scale of the time) plus the re-charges add up to the final ``s``
    times all the work the cells reported."""
    track, charged, total = UNCHECKED, 0.0, 0.0
    load = load_for(tau)
    for k, w in enumerate(intos * 3):
        f = FingerState(PROXIMAL_RAD, 0.5, 1.0, load + (k % 3), (), ())
        track, r = step_gain(track, f, gain * tau, w, DT_S, MODEL)
        charged += track.scale * w + r
        total += w
    assert charged == pytest.approx(track.scale * total, rel=1e-9, abs=1e-12)


def test_check_gains_hands_the_works_back_untouched_until_a_finger_is_flagged() -> None:
    """Nothing changes while the check does not fire (the lockstep digests rely on it); a
    flagged finger's work into the object is scaled, its work back credited as read."""
    pads = tuple(PadTrack(PROXIMAL_RAD, 0.5, 5.0, 0.04) for _ in range(3))
    works = ((0.01, 0.002), (0.0, 0.0), (0.003, 0.0))
    f = FingerState(PROXIMAL_RAD, 0.5, 1.0, load_for(0.2), (), ())
    tracks, out, r = check_gains(MODEL, (UNCHECKED,) * 3, pads, (f,) * 3, works, DT_S)
    assert out is works and r == 0.0
    flagged = GainTrack(scale=2.5)
    _, out, _ = check_gains(MODEL, (flagged, UNCHECKED, UNCHECKED), pads, (f,) * 3, works,
                            DT_S)
    assert out == ((0.025, 0.002), (0.0, 0.0), (0.003, 0.0))


def test_the_servo_moment_is_the_contact_moment_of_the_finger_statics() -> None:
    assert servo_moment_nm(load_for(0.37, 1.1), 1.1, MODEL) == pytest.approx(0.37)
    # no load at rest off the stop: the spring's moment, with no contact to hold it
    assert servo_moment_nm(0.0, 0.0, MODEL) == pytest.approx(
        -MODEL.base_spring_nm_per_rad * MODEL.base_preload_rad)


def _pressing(proximal_rad: float, force_n: float) -> FingerState:
    """A finger pressing ``force_n`` on its proximal pad at the middle cell (true gain)."""
    cells = tuple(MODEL.pressure_per_n * force_n * kernel(MODEL, x - 0.0347)
                  for x in MODEL.proximal_sensor_x_m)
    pressure = cells + (0.0,) * 4
    return FingerState(proximal_rad, 0.0, proximal_rad, 0.0, pressure,
                       tuple(v > 20.0 for v in pressure))


def pressing_sample(gains: tuple[GainTrack, ...]) -> tuple[float, HandOutput]:
    """One sample of the two-layer hand in which every finger's pad, pressing 5 N, moves
    0.01 rad into the object, its check's tracks ``gains`` before it: ``(what the tank
    paid, the hand's output)``."""
    p = replace(control_params(ControllerConfig()), transfer_fraction=0.0)
    cmd = HandCommand(header=Header(seq=1, t_s=0.0, energy_total_j=0.0),
                      finger_setpoint_rad=(0.5,) * 3, preshape_rad=0.0, mode=HandMode.POSITION)
    s = two_layer.init_hand(p)
    s, _ = two_layer.step_hand_object(s, p, (_pressing(0.2, 5.0),) * 3, cmd, DT_S)
    s = replace(s, gains=gains)
    before = s.ledger.port_out_j
    s, out = two_layer.step_hand_object(s, p, (_pressing(0.21, 5.0),) * 3, cmd, DT_S)
    return s.ledger.port_out_j - before, out


def _charged_j(gains: tuple[GainTrack, ...]) -> float:
    """What the tank pays for :func:`pressing_sample`."""
    return pressing_sample(gains)[0]


def test_the_hand_layer_charges_a_flagged_fingers_work_at_its_scale() -> None:
    """The wiring: one finger flagged at ``s = 2.5`` costs the tank 2.5x its share, the
    others as before (the work is ``m F r dt``: 1.15 x 5 N x ~35 mm x 0.01 rad)."""
    plain = _charged_j((UNCHECKED,) * 3)
    assert plain == pytest.approx(3 * 1.15 * 5.0 * 0.0347 * 0.01, rel=0.05)
    flagged = _charged_j((GainTrack(scale=2.5), UNCHECKED, UNCHECKED))
    assert flagged == pytest.approx(plain * (2.5 + 2) / 3, rel=1e-9)


def test_the_hand_layer_pays_the_recharge_through_the_margin_beyond_the_sample_cap(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The wiring of the re-charge: a check that re-charges 1 J in a sample (far more than the
    one-sample cap of ~0.05 J) costs the tank ``m`` x 1 J on top of the sample's work."""
    plain = _charged_j((UNCHECKED,) * 3)
    checks = gain_check.check_gains
    patch_sides(monkeypatch, "check_gains",
                        lambda *a: (*checks(*a)[:2], 1.0))
    assert _charged_j((UNCHECKED,) * 3) == pytest.approx(plain + MODEL.force_margin * 1.0,
                                                         rel=1e-9)


# ------------------------------------------------------------------------- kept mutants
def _flipped(lower_nm: float, cells_nm: float, margin: float) -> bool:
    return lower_nm < margin * cells_nm


def _margin_ignored(lower_nm: float, cells_nm: float, margin: float) -> bool:
    return lower_nm > cells_nm


CHECKS: dict[str, Callable[[], None]] = {
    "true": test_cells_that_read_the_servos_moment_are_never_flagged,
    "third": test_cells_reading_a_third_are_flagged_after_two_held_windows,
    "margin": test_cells_low_within_their_margin_are_not_flagged,
    "high": test_cells_reading_high_are_never_flagged,
}
MUTANTS = {"comparison flipped": _flipped, "margin ignored": _margin_ignored}


def _fails(check: Callable[[], None]) -> bool:
    try:
        check()
    except (AssertionError, StopIteration):
        return True
    return False


@pytest.mark.parametrize("name", sorted(MUTANTS))
def test_a_broken_verdict_fails_a_check(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(gain_check, "reads_low", MUTANTS[name])
    assert any(_fails(c) for c in CHECKS.values()), f"mutant {name!r} passed every check"


def test_the_checks_pass_on_the_verdict_as_it_is() -> None:
    assert not any(_fails(c) for c in CHECKS.values())


def test_the_kept_mutants_are_real_verdicts() -> None:
    """Each mutant differs from the verdict on some input (else it could not be caught)."""
    for mutant in MUTANTS.values():
        assert any(mutant(lo, c, 1.15) != gain_check.reads_low(lo, c, 1.15)
                   for lo in (0.1, 0.5, 1.0) for c in (0.09, 0.45, 0.9, 2.0))
