"""The two-layer hand's environment port (``hand_port = "object"``): the tactile work estimate
against the finger model's own contact physics, the reservation, and the hand step.

The readings come from the simulator's sensor law (``sim.contact.sensor_pressures``) and the
true work from the contact's force times the pad's normal motion, computed here, so the
estimate is checked against code it does not share."""

from __future__ import annotations

import math
import random
from dataclasses import replace

import pytest

from sim.contact import sensor_pressures
from sim.params import default_finger_params
from teleop.config.control import ControllerConfig
from teleop.control import two_layer
from teleop.control.interface import control_params
from teleop.control.object_port import (
    TactileModel,
    contact_estimate,
    margin_charge_j,
    track_finger,
    track_fingers,
    track_start,
)
from teleop.control.passivity_layer import hand_reservation_j, reservation_j, reserve_project
from teleop.messages import FingerState, HandCommand, HandMode, Header

FP = default_finger_params()
MODEL = TactileModel()
P = control_params(ControllerConfig())
K, TMAX, KT = P.servo_stiffness_nm_per_rad, P.servo_torque_max_nm, P.tendon_stiffness_nm_per_rad


def reading(prox_n: float, prox_x: float, dist_n: float = 0.0, dist_x: float = 0.02,
            gain: float = 1.0) -> tuple[float, ...]:
    return tuple(gain * v for v in sensor_pressures(FP, prox_n, prox_x, dist_n, dist_x))


def state(prox: float, pressure: tuple[float, ...], dist: float = 0.0) -> FingerState:
    return FingerState(proximal_rad=prox, distal_rad=dist, motor_angle_rad=prox + dist,
                       load_units=0.0, pressure=pressure,
                       contact=tuple(v > 20.0 for v in pressure))


@pytest.mark.parametrize("x_m", [0.012, 0.019, 0.023, 0.031, 0.0347, 0.041, 0.048, 0.05])
def test_force_and_place_are_recovered_anywhere_on_the_proximal_pad(x_m: float) -> None:
    f, x = contact_estimate(MODEL, reading(4.0, x_m)[:5], MODEL.proximal_sensor_x_m,
                            MODEL.proximal_pad_m)
    assert f == pytest.approx(4.0, rel=0.12)
    assert abs(x - x_m) < 0.003


def test_no_reading_no_contact() -> None:
    assert contact_estimate(MODEL, (0.0,) * 5, MODEL.proximal_sensor_x_m) == (0.0, 0.0)
    assert contact_estimate(MODEL, (3.0, -2.0, math.nan, 1.0, 0.0),
                            MODEL.proximal_sensor_x_m)[0] == 0.0


def press_and_release(k_n_per_m: float, x_m: float, gain: float = 1.0, noise_rad: float = 0.0,
                      hold_steps: int = 40, seed: int = 0,
                      stop_at_peak: bool = False) -> tuple[float, float, float, float]:
    """A proximal pad at ``x_m`` rotates into a spring object (touching at 0.3 rad) and back,
    sampled at 40 Hz with encoder noise: (estimated delivered, estimated taken, true
    delivered, true taken)."""
    rng = random.Random(seed)
    path = ([0.25 + 0.005 * i for i in range(40)] + [0.445] * hold_steps
            + ([] if stop_at_peak else [0.445 - 0.005 * i for i in range(40)]))
    track = None
    est_out = est_in = true_out = true_in = 0.0
    prev_depth = 0.0
    for theta in path:
        depth = max(0.0, (theta - 0.3) * x_m)
        w = 0.5 * k_n_per_m * (depth * depth - prev_depth * prev_depth)
        true_out += max(w, 0.0)
        true_in += max(-w, 0.0)
        prev_depth = depth
        fs = state(theta + rng.gauss(0.0, noise_rad), reading(k_n_per_m * depth, x_m, gain=gain))
        if track is None:
            track = track_start(fs)
            continue
        track, o, i = track_finger(MODEL, track, fs)
        est_out += o
        est_in += i
    return est_out, est_in, true_out, true_in


@pytest.mark.parametrize("k_n_per_m", [300.0, 2000.0, 5000.0])
@pytest.mark.parametrize("x_m", [0.02, 0.035, 0.049])
def test_estimate_is_on_the_safe_side(k_n_per_m: float, x_m: float) -> None:
    est_out, est_in, true_out, true_in = press_and_release(k_n_per_m, x_m)
    assert est_out >= true_out
    assert est_in <= true_in
    # and not absurdly so: an elastic press and release costs well under what it stored (the
    # 40 Hz sampling: sum dF ds)
    assert est_out - est_in <= 0.5 * true_out + 1e-4


@pytest.mark.parametrize("gain", [0.9, 1.1])
def test_a_sensor_off_by_ten_percent_stays_on_the_safe_side_over_a_cycle(gain: float) -> None:
    est_out, est_in, true_out, true_in = press_and_release(2000.0, 0.035, gain=gain)
    assert margin_charge_j(MODEL, est_out - est_in) >= true_out - true_in
    # and at the top of the press, where the object holds the most
    peak_est, _, peak_true, _ = press_and_release(2000.0, 0.035, gain=gain, hold_steps=0,
                                                  stop_at_peak=True)
    assert margin_charge_j(MODEL, peak_est) >= peak_true


def test_encoder_noise_during_a_hold_costs_little() -> None:
    quiet = press_and_release(2000.0, 0.035, hold_steps=400)
    noisy = press_and_release(2000.0, 0.035, noise_rad=0.002, hold_steps=400, seed=3)
    assert noisy[0] - noisy[1] >= noisy[2] - noisy[3]  # still safe
    # 10 s of noisy hold costs less than the elastic energy of the press itself
    assert (noisy[0] - noisy[1]) - (quiet[0] - quiet[1]) < quiet[2]


def test_free_motion_costs_nothing() -> None:
    fingers = tuple(state(0.1, (0.0,) * 9) for _ in range(3))
    tracks, works = track_fingers(MODEL, None, fingers)
    assert works == ((0.0, 0.0),) * 3
    moved = tuple(state(1.5, (0.0,) * 9) for _ in range(3))
    _, works = track_fingers(MODEL, tracks, moved)
    assert works == ((0.0, 0.0),) * 3


def test_reservation_covers_servo_and_tendon() -> None:
    assert reservation_j(-0.3, K, TMAX, KT) == 0.0
    e = 0.2
    assert math.isclose(reservation_j(e, K, TMAX, KT),
                        0.5 * K * e * e + 0.5 * (K * e) ** 2 / KT)
    # beyond saturation the tendon part stops growing
    big = reservation_j(2.0, K, TMAX, KT) - reservation_j(1.9, K, TMAX, KT)
    assert math.isclose(big, TMAX * 0.1, rel_tol=1e-9)


@pytest.mark.parametrize("budget", [-1.0, 0.0, 0.01, 0.3, 5.0, 100.0])
def test_projection_never_reserves_more_than_the_budget(budget: float) -> None:
    x = (0.5, 0.8, 1.0)
    want = (2.5, 0.2, 3.0)  # two closing, one opening
    y, limited = reserve_project(want, x, budget, K, TMAX, KT)
    need = hand_reservation_j(y, x, K, TMAX, KT)
    assert need <= max(budget, 0.0) + 1e-12
    assert limited == (hand_reservation_j(want, x, K, TMAX, KT) > budget)
    assert y[1] <= x[1]  # the opening finger is never held back


def command(y: float) -> HandCommand:
    return HandCommand(header=Header(seq=1, t_s=0.0, energy_total_j=0.0),
                       finger_setpoint_rad=(y, y, y), preshape_rad=0.0, mode=HandMode.POSITION)


def test_an_empty_tank_holds_the_fingers_where_they_are_but_lets_them_open() -> None:
    p = replace(P, initial_j=0.0, min_j=0.0, servo_max_speed_rad_s=1e6)
    s = two_layer.init_hand(p)
    fs = tuple(state(0.6, (0.0,) * 9) for _ in range(3))
    s, out = two_layer.step_hand(s, p, fs, command(2.0), 0.025)
    assert out.limited and all(v <= 0.6 + 1e-12 for v in out.setpoint_rad)
    s, out = two_layer.step_hand(s, p, fs, command(0.1), 0.025)
    assert out.setpoint_rad == pytest.approx((0.1, 0.1, 0.1)) and not out.limited


def test_pressing_is_charged_and_releasing_credited_by_the_hand_step() -> None:
    p = replace(P, transfer_fraction=0.0, max_j=100.0)
    s = two_layer.init_hand(p)
    levels = []
    for theta in [0.3, 0.35, 0.4, 0.45, 0.4, 0.35, 0.3]:
        depth = max(0.0, (theta - 0.3) * 0.035)
        fs = tuple(state(theta, reading(2000.0 * depth, 0.035)) for _ in range(3))
        s, out = two_layer.step_hand(s, p, fs, command(theta), 0.025)
        levels.append(s.ledger.tank_j)
    assert levels[3] < levels[0]  # pressing cost energy
    assert levels[-1] > levels[3]  # the object gave some back
    assert levels[-1] < levels[0]  # never more than it took
    assert s.ledger.port_out_j > s.ledger.port_in_j > 0.0


def test_the_bisected_near_rows_and_written_out_sums_match_the_plain_fit() -> None:
    """``contact_estimate`` (rows near the tracked point by bisection, cell sums written out)
    against the plain definition: every row tested, ``sum`` of the products."""
    from teleop.control.object_port import TRACK_STEP_M, _kernel_table

    m = TactileModel()
    rng = random.Random(5)

    def plain(cells: tuple[float, ...], xs: tuple[float, ...], pad: tuple[float, float] | None,
              near: float | None) -> tuple[float, float]:
        p = [max(v, 0.0) if math.isfinite(v) else 0.0 for v in cells]
        if max(p) <= m.noise_floor:
            return 0.0, 0.0
        strong = pad is not None and max(p) >= 4.0 * max(m.noise_floor, 1.0)
        table = _kernel_table(m, xs, *(pad if strong and pad is not None else (xs[0], xs[-1])))
        rows = table
        if near is not None and near > 0.0:
            rows = [r for r in table if abs(r[0] - near) <= TRACK_STEP_M + 1e-12] or table
        best = (-1.0, 0.0, 0.0)
        for x, ks, kk in rows:
            pk = sum([a * b for a, b in zip(p, ks, strict=True)])
            if pk * pk / kk > best[0]:
                best = (pk * pk / kk, x, pk / kk)
        return best[2] / m.pressure_per_n, best[1]

    for _ in range(300):
        prox = rng.random() < 0.5
        xs = m.proximal_sensor_x_m if prox else m.distal_sensor_x_m
        pad = (m.proximal_pad_m if prox else m.distal_pad_m) if rng.random() < 0.8 else None
        cells = tuple(rng.choice([0.0, rng.uniform(-5, 300), rng.uniform(0, 30), math.nan])
                      for _ in xs)
        near = rng.choice([None, 0.0, rng.uniform(0.0, 0.07), math.inf])
        assert repr(contact_estimate(m, cells, xs, pad, near)) == repr(plain(cells, xs, pad,
                                                                            near))
