"""The unseen-contact guard's step on its own: chords of proximal against motor advance."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from teleop.control.stall_guard import FREE, StallTrack, stall_recharge_j, step_stall

WINDOW, RATIO, CURL = 0.1, 0.3, 0.45


def follow(motor: np.ndarray, proximal: np.ndarray, force: np.ndarray | float = 0.0,
           window: float = WINDOW) -> list[StallTrack]:
    """The guard along a trajectory (one sample per entry)."""
    f = np.broadcast_to(np.asarray(force, float), motor.shape)
    s, out = FREE, []
    for m, p, fn in zip(motor, proximal, f, strict=True):
        s = step_stall(s, float(m), float(p), float(fn), window, RATIO, CURL)
        out.append(s)
    return out


def closing(stall_at_rad: float | None, end_rad: float = 2.5, n: int = 2000) -> tuple[
        np.ndarray, np.ndarray]:
    """A ReFlex-like closing: the distal link curls first (proximal still until the motor has
    run 0.3 rad ahead), then the proximal follows at 0.95 of the motor's rate; against an
    object at ``stall_at_rad`` (proximal) it advances 5 % of the motor's rate."""
    motor = np.linspace(0.0, end_rad, n)
    prox = np.maximum(motor - 0.3, 0.0) * 0.95
    if stall_at_rad is not None:
        k = int(np.argmax(prox >= stall_at_rad)) if np.any(prox >= stall_at_rad) else n
        prox[k:] = prox[k] + 0.05 * (motor[k:] - motor[k])
    return motor, prox


def test_free_motion_is_never_flagged() -> None:
    motor, prox = closing(None)
    assert not any(s.stalled for s in follow(motor, prox))


def test_the_distal_curl_alone_is_not_a_stall() -> None:
    """The first phase of a closing: the proximal link still, the motor less than the free
    curl ahead of it."""
    motor = np.linspace(0.0, CURL - 0.01, 400)
    assert not any(s.stalled for s in follow(motor, np.zeros_like(motor)))


def test_a_stall_with_silent_cells_is_flagged_within_the_curl_and_two_windows() -> None:
    motor, prox = closing(0.2)
    track = follow(motor, prox)
    first = next(i for i, s in enumerate(track) if s.stalled)
    k = int(np.argmax(prox >= 0.2))
    # flagged once the motor is past the free curl, at most two windows later
    assert motor[first] - prox[first] > CURL
    assert motor[first] - motor[k] <= CURL - 0.3 + 0.2 + 2 * WINDOW
    assert all(s.stalled for s in track[first:])


def test_a_stall_the_cells_see_is_not_flagged() -> None:
    motor, prox = closing(0.2)
    force = np.where(prox >= 0.2, 3.0, 0.0)
    assert not any(s.stalled for s in follow(motor, prox, force))


def test_a_force_seen_anywhere_in_the_chord_clears_it() -> None:
    """A cell seen for one sample of the chord (a flickering contact) keeps the chord from
    flagging: only a chord that saw nothing at all is blind."""
    motor, prox = closing(0.2)
    force = np.zeros_like(motor)
    force[::30] = 1.0  # one sample in 30: every 0.1 rad chord (80 samples) sees some
    assert not any(s.stalled for s in follow(motor, prox, force))


def test_the_flag_holds_while_squeezing_and_clears_a_window_behind_the_stall() -> None:
    """Backing off part of the way keeps the flag (the object is still there: squeezing again
    is charged); backing out a window behind where the stall was flagged frees the finger."""
    motor, prox = closing(0.2, end_rad=1.2, n=1000)
    track = follow(motor, prox)
    first = next(i for i, s in enumerate(track) if s.stalled)
    at = track[first].stall_motor_rad
    back = np.linspace(1.2, at - 2 * WINDOW, 400)
    p = np.concatenate([prox, np.full_like(back, prox[-1])])
    track = follow(np.concatenate([motor, back]), p)
    held = [s.stalled for s, m in zip(track[1000:], back, strict=True) if m > at - WINDOW]
    freed = [s.stalled for s, m in zip(track[1000:], back, strict=True)
             if m < at - WINDOW - 0.01]
    assert held and all(held)
    assert freed and not any(freed)


def test_window_zero_turns_it_off() -> None:
    motor, prox = closing(0.2)
    assert not any(s.stalled for s in follow(motor, prox, window=0.0))


@settings(max_examples=60, deadline=None)
@given(rate=st.floats(0.6, 1.2), curl=st.floats(0.0, CURL - 0.05), noise=st.floats(0.0, 0.002),
       seed=st.integers(0, 2**16))
def test_any_free_closing_within_the_model_is_not_flagged(rate: float, curl: float,
                                                          noise: float, seed: int) -> None:
    """A first phase within the free curl, then a proximal following at 0.6-1.2 of the
    motor's rate (below 1 the motor runs further and further ahead of it, past the curl gate:
    the ratio gate holds) with encoder noise up to 2 mrad (the ReFlex's 12-bit encoder:
    1.5 mrad) is never flagged."""
    rng = np.random.default_rng(seed)
    motor = np.linspace(0.0, 2.5, 1500)
    prox = np.maximum(motor - curl, 0.0) * rate + rng.normal(0.0, noise, motor.size)
    assert not any(s.stalled for s in follow(motor, prox))


def test_the_flag_recharges_the_winding_of_the_chord_that_found_it() -> None:
    """The chord that finds the stall was charged nothing (the cells are silent): when the
    flag is raised :func:`stall_recharge_j` charges ``tau_max`` times the motor's inward
    motion over it before the flagging sample (whose own motion is the yield guard's
    per-sample charge), the steps back not netted out, once."""
    motor, prox = closing(0.2)
    motor = motor.copy()
    motor[1::9] -= 0.002  # now and then a step back
    s, m_prev, states = FREE, None, []
    for m, p in zip(motor, prox, strict=True):
        s = step_stall(s, float(m), float(p), 0.0, WINDOW, RATIO, CURL, m_prev)
        states.append(s)
        m_prev = float(m)
    flag = next(i for i, g in enumerate(states) if g.stalled)
    before = states[flag - 1]
    assert before.anchor_motor_rad is not None
    start = max(i for i in range(flag) if states[i].anchor_motor_rad == motor[i])
    inward = sum(max(motor[i] - motor[i - 1], 0.0) for i in range(start + 1, flag))
    assert before.wound_rad == pytest.approx(inward, rel=1e-12)
    assert inward > motor[flag - 1] - before.anchor_motor_rad  # the steps back not netted
    assert inward >= WINDOW - (motor[flag] - motor[flag - 1])
    assert stall_recharge_j((before, FREE), (states[flag], FREE), 3.0) == \
        pytest.approx(3.0 * inward)
    # once: never again while the flag holds (the later chords wind on)
    assert any(g.wound_rad > 0.0 for g in states[flag:])
    assert sum(stall_recharge_j((a,), (b,), 3.0)
               for a, b in zip(states[flag:], states[flag + 1:], strict=False)) == 0.0
    # without the previous angle nothing is wound (the guard's verdicts unchanged)
    plain = follow(motor, prox)
    assert [g.stalled for g in plain] == [g.stalled for g in states]
    assert all(g.wound_rad == 0.0 for g in plain)
