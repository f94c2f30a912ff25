"""The yielding-contact guard on force-against-advance curves it must and must not flag.

Each curve is fed as the hand would see it: the estimated total pad force at every sample and
the pads' advance over the sample.
The guard may only use the curve's shape, so a gain error (every force and work scaled
alike) must never change its verdict.
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable
from dataclasses import replace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from teleop.control.yield_guard import (
    NO_CONTACT,
    SET_FOUND,
    YieldTrack,
    flag_recharge_j,
    pad_advance_m,
    step_yield,
    took_a_set,
    yield_charge_j,
)

WINDOW_M = 0.001
RATIO = 0.2


def feed(force_of: Callable[[float], float], depths_m: list[float], gain: float = 1.0,
         noise_n: float = 0.0, seed: int = 0) -> list[YieldTrack]:
    """The guard's states along a path of true pad depths, with cells of gain ``gain``."""
    rng = random.Random(seed)
    g, out = NO_CONTACT, []
    d_prev = depths_m[0]
    for d in depths_m:
        f = max(gain * force_of(d) + (rng.gauss(0.0, noise_n) if noise_n else 0.0), 0.0)
        g = step_yield(g, f, d - d_prev, 10.0 * d, WINDOW_M, RATIO)  # motor follows
        out.append(g)
        d_prev = d
    return out


def ramp(to_m: float, n: int = 200, start_m: float = 0.0) -> list[float]:
    return [start_m + (to_m - start_m) * i / n for i in range(n + 1)]


def linear(k: float, onset_m: float = 0.0) -> Callable[[float], float]:
    return lambda d: k * (d + onset_m) if d >= 0.0 else 0.0


def crushing(k: float, yield_n: float) -> Callable[[float], float]:
    return lambda d: min(k * d, yield_n) if d >= 0.0 else 0.0


def with_core(k: float, core_m: float, k_core: float) -> Callable[[float], float]:
    return lambda d: k * d + (k_core * (d - core_m) if d > core_m else 0.0)


@pytest.mark.parametrize("force", [linear(2000.0), linear(300.0), linear(5000.0),
                                   linear(2000.0, onset_m=0.004),
                                   with_core(300.0, 0.012, 2e5),
                                   lambda d: 4e6 * max(d, 0.0) ** 1.5],  # Hertz-like
                         ids=["stiff", "soft", "block", "late-onset", "core", "stiffening"])
def test_elastic_contacts_are_never_flagged(force: Callable[[float], float]) -> None:
    path = ramp(0.014)
    assert not any(g.yielding for g in feed(force, path))


def test_an_elastic_squeeze_in_and_out_and_in_again_is_not_flagged() -> None:
    path = ramp(0.008) + ramp(0.002, start_m=0.008) + ramp(0.010, start_m=0.002)
    assert not any(g.yielding for g in feed(linear(2000.0), path, noise_n=0.05, seed=1))


def test_a_crushing_contact_is_flagged_within_three_windows_of_the_yield() -> None:
    k, fy = 2000.0, 3.0
    path = ramp(0.012)
    states = feed(crushing(k, fy), path)
    first = next(i for i, g in enumerate(states) if g.yielding)
    assert path[first] - fy / k <= 3 * WINDOW_M
    assert all(g.yielding for g in states[first:])  # latched while in contact


def test_the_flag_clears_when_the_contact_ends() -> None:
    states = feed(crushing(2000.0, 3.0), ramp(0.012) + [-0.001])
    assert states[-2].yielding and states[-1] == NO_CONTACT


@pytest.mark.parametrize("noise_n", [0.0, 0.03, 0.06])
def test_noise_does_not_flag_a_soft_elastic_contact(noise_n: float) -> None:
    for seed in range(10):
        assert not any(g.yielding for g in feed(linear(300.0), ramp(0.012, n=400),
                                                noise_n=noise_n, seed=seed))


@settings(max_examples=60, deadline=None)
@given(gain=st.floats(0.05, 20.0), k=st.floats(200.0, 8000.0), yield_n=st.floats(0.5, 8.0),
       crush=st.booleans())
def test_the_verdict_does_not_depend_on_the_cells_gain(gain: float, k: float, yield_n: float,
                                                        crush: bool) -> None:
    force = crushing(k, yield_n) if crush else linear(k)
    path = ramp(0.012)
    ref = [g.yielding for g in feed(force, path)]
    assert [g.yielding for g in feed(force, path, gain=gain)] == ref
    if crush and yield_n / k < 0.012 - 4 * WINDOW_M:
        assert ref[-1]


def test_the_guard_off_never_flags() -> None:
    g = NO_CONTACT
    for d in ramp(0.012):
        f = min(2000.0 * d, 3.0)
        g = step_yield(g, f, 6e-5, 10.0 * d, WINDOW_M, 0.0)
    assert g.in_contact and not g.yielding


def test_the_charge_is_the_servo_torque_times_inward_motion_of_yielding_fingers() -> None:
    x_prev = (0.10, 0.20, 0.30)
    x = (0.15, 0.18, 0.40)
    assert math.isclose(yield_charge_j(x, x_prev, (True, True, False), 3.55), 3.55 * 0.05)
    assert yield_charge_j(x, x_prev, (False, False, False), 3.55) == 0.0


@pytest.mark.parametrize("gain", [1.0, 1.0 / 3.0])
def test_a_noisy_crushing_contact_read_low_is_flagged(gain: float) -> None:
    for seed in range(5):
        states = feed(crushing(2000.0, 3.0), ramp(0.012), gain=gain, noise_n=0.03, seed=seed)
        assert states[-1].yielding


def test_the_advance_weights_each_pad_by_its_force_and_lever() -> None:
    # proximal pad alone at 30 mm: r dtp
    assert math.isclose(pad_advance_m((2.0, 0.0), (0.03, 0.0), 0.01, 0.0, 0.076), 3e-4)
    # distal pad alone at 20 mm, distal bend 0: (L + r) dtp; gain-free (forces scaled alike)
    a = pad_advance_m((0.0, 5.0), (0.0, 0.02), 0.01, 0.0, 0.076)
    assert math.isclose(a, 0.096e-2)
    assert math.isclose(pad_advance_m((0.0, 0.5), (0.0, 0.02), 0.01, 0.0, 0.076), a)
    assert pad_advance_m((0.0, 0.0), (0.0, 0.0), 0.01, 0.0, 0.076) == 0.0


def test_a_force_falling_while_the_motor_lets_go_is_not_a_yield() -> None:
    """After a loading (force rising with advance, the motor winding in), the pads still
    advance (the finger unbends) while the servo unwinds and the force drops: an unloading.
    The same curve with the motor still winding in is flagged."""
    def run(motor_back: bool) -> YieldTrack:
        g = NO_CONTACT
        for i in range(40):  # loading: 2000 N/m over 8 mm, motor winding in
            g = step_yield(g, 0.5 + 2000.0 * 0.0002 * i, 0.0002, 0.01 * i, WINDOW_M, RATIO)
        for i in range(40):  # pads advance 8 mm more, the force falls
            motor = 0.4 - 0.01 * i if motor_back else 0.4 + 0.01 * i
            g = step_yield(g, 16.5 - 0.3 * i, 0.0002, motor, WINDOW_M, RATIO)
        return g

    unloaded = run(motor_back=True)
    assert unloaded.in_contact and not unloaded.yielding
    assert run(motor_back=False).yielding


def test_the_flag_recharges_the_winding_of_the_episode_before_it() -> None:
    """The episode's winding counts the motor's inward motion from the sample in which the
    force was first seen (that sample's own motion included), never its backing out; when
    the flag is raised, :func:`flag_recharge_j` charges ``tau_max`` times the winding before
    the flagging sample (whose own motion is :func:`yield_charge_j`'s), once."""
    depths = ramp(0.02, n=400)
    force = crushing(5000.0, 10.0)
    g, motor_prev, states = NO_CONTACT, -0.01, []
    for i, d in enumerate(depths):
        motor = 10.0 * d - (0.004 if i % 7 == 3 else 0.0)  # now and then a step back
        g = step_yield(g, force(d), d - depths[max(i - 1, 0)], motor, WINDOW_M, RATIO,
                       motor_prev)
        states.append((g, motor, motor_prev))
        motor_prev = motor
    flag = next(i for i, (g, _, _) in enumerate(states) if g.yielding)
    inward = sum(max(m - mp, 0.0) for g, m, mp in states[:flag] if g.in_contact)
    assert states[flag - 1][0].wound_rad == pytest.approx(inward, rel=1e-12)
    assert inward > 10.0 * depths[flag - 1]  # the steps back are not netted out
    before, after = states[flag - 1][0], states[flag][0]
    assert flag_recharge_j((before,) * 3, (after, NO_CONTACT, before), 2.0) == \
        pytest.approx(2.0 * inward, rel=1e-12)
    # already flagged: nothing more; a new episode starts its winding afresh
    assert flag_recharge_j((after,), (states[flag + 1][0],), 2.0) == 0.0
    fresh = step_yield(NO_CONTACT, 1.0, 0.0, 0.5, WINDOW_M, RATIO, 0.45)
    assert fresh.wound_rad == pytest.approx(0.05)
    assert step_yield(after, 0.0, 0.0, 0.3, WINDOW_M, RATIO, 0.2) == NO_CONTACT


class Plastic:
    """An elastic-perfectly-plastic contact: ``k (d - set)``, capped at ``yield_n``, the set
    growing by what the cap cuts off (a dent that stays when the pads back out)."""

    def __init__(self, k: float, yield_n: float) -> None:
        self.k, self.yield_n, self.set_m = k, yield_n, 0.0

    def __call__(self, d: float) -> float:
        if self.k * (d - self.set_m) > self.yield_n:
            self.set_m = d - self.yield_n / self.k
        return max(self.k * (d - self.set_m), 0.0)


def in_and_out(force_of: Callable[[float, float], float], depths_m: list[float],
               gain: float = 1.0, ratio: float = RATIO) -> list[YieldTrack]:
    """The guard's states along ``depths_m`` (in and back out), the force a function of the
    depth and the last sample's motion, the motor winding in and out with the pads."""
    g, out, d_prev = NO_CONTACT, [], depths_m[0]
    for d in depths_m:
        f = gain * force_of(d, d - d_prev)
        g = step_yield(g, f, d - d_prev, 10.0 * d, WINDOW_M, ratio, 10.0 * d_prev)
        out.append(g)
        d_prev = d
    return out


#: pressed 3.2 mm into a skin that yields at 1.5 mm (1.7 mm of crushing: fewer than two
#: windows, so no two flat chords), then backed out past where it started
QUICK_CRUSH = ramp(0.0032, n=80) + ramp(-0.001, n=40, start_m=0.0032)[1:]


@pytest.mark.parametrize("gain", [1.0, 1.0 / 3.0, 0.01])
def test_a_quick_crush_is_found_by_the_set_it_leaves(gain: float) -> None:
    """Too brief for two flat chords, the crush is not flagged while it lasts; when the
    contact ends the pads stand 1.7 mm beyond where the loading path had the same force:
    the finger is flagged for that sample (whatever the cells' gain) and the episode's
    winding is re-charged."""
    plastic = Plastic(2000.0, 3.0)
    states = in_and_out(lambda d, _s: plastic(d), QUICK_CRUSH, gain)
    end = next(i for i, g in enumerate(states) if i and not g.in_contact)
    assert not any(g.yielding for g in states[:end])
    assert states[end] == SET_FOUND
    assert states[end - 1].wound_rad > 0.0
    assert flag_recharge_j((states[end - 1],), (states[end],), 2.0) == \
        pytest.approx(2.0 * states[end - 1].wound_rad)
    assert states[end + 1] == NO_CONTACT  # one sample only


@pytest.mark.parametrize("force", [
    lambda d, _s: 2000.0 * max(d, 0.0),
    lambda d, _s: 4e6 * max(d, 0.0) ** 1.5,
    # a damper: the force while backing out (0.4 mm a 25 ms sample) is 2.16 N below the
    # spring's, so it ends 1.08 mm in, within one window plus half a sample's motion
    lambda d, step: max(2000.0 * d + 135.0 * step / 0.025, 0.0) if d > 0.0 else 0.0,
], ids=["linear", "stiffening", "damped"])
def test_an_elastic_contact_in_and_out_leaves_no_set(force: Callable[[float, float], float]
                                                      ) -> None:
    path = ramp(0.008, n=160) + ramp(-0.001, n=22, start_m=0.008)[1:]
    states = in_and_out(force, path)
    assert not states[-1].in_contact
    assert not any(g.yielding for g in states)


def test_a_contact_already_flagged_is_not_flagged_again_at_its_end() -> None:
    plastic = Plastic(2000.0, 3.0)
    states = in_and_out(lambda d, _s: plastic(d), ramp(0.012, n=200) + [-0.001])
    assert states[-2].yielding and states[-1] == NO_CONTACT


def test_the_set_check_is_off_with_the_guard() -> None:
    plastic = Plastic(2000.0, 3.0)
    states = in_and_out(lambda d, _s: plastic(d), QUICK_CRUSH, ratio=0.0)
    assert not any(g.yielding for g in states)


def test_the_loading_path_keeps_points_five_percent_apart() -> None:
    """The path is bounded (a point per 5 % of force, not per sample) and the set is judged
    against the first point at or above the last force: not one window further in."""
    states = in_and_out(lambda d, _s: 2000.0 * max(d, 0.0), ramp(0.008, n=400))
    path = states[-1].loading
    assert len(path) < 80
    assert all(b[0] >= 1.05 * a[0] for a, b in zip(path, path[1:], strict=False))
    g = replace(states[-1], force_n=8.0, step_m=0.0)
    q4 = next(q for f, q in path if f >= 8.0)
    assert not took_a_set(replace(g, advance_m=q4 + WINDOW_M), WINDOW_M)
    assert took_a_set(replace(g, advance_m=q4 + 1.01 * WINDOW_M), WINDOW_M)
