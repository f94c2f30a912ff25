"""Physical invariants of the finger model and the report's qualitative facts."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from sim.experiments import ExperimentSpec, run_experiment
from sim.finger import (
    NO_EFFECTS,
    ContactObject,
    MotorCommand,
    default_finger_params,
    finger_energy_j,
    finger_outputs,
    finger_step,
    initial_finger_state,
)
from sim.params import JOINT_RATIO

P = default_finger_params()
NONE = ContactObject()
CYL = ContactObject(kind="cylinder", x_m=0.045, y_m=0.03, radius_m=0.02)


def _energy_trace(state, cmd, steps=3000):
    energies = [finger_energy_j(state, P)]
    for _ in range(steps):
        state = finger_step(state, cmd, P, NONE, NO_EFFECTS, 1e-3)
        energies.append(finger_energy_j(state, P))
    return np.array(energies), state


def test_energy_of_unforced_damped_finger_never_increases() -> None:
    # finger released from a bent, moving pose; tendon slack (motor far back), no motor effort
    st = replace(initial_finger_state(P), prox_rad=1.2, prox_vel_rad_s=2.0,
                 flex_rad=(0.3, 0.2, 0.35, 0.1), flex_vel_rad_s=(1.0, -1.0, 0.5, 0.0),
                 motor_rad=-5.0)
    e, end = _energy_trace(st, MotorCommand("force", force_units=0.0))
    assert np.all(np.diff(e) <= 1e-12)
    assert e[-1] < 0.5 * e[0] or end.prox_rad == 0.0


def test_energy_with_taut_tendon_and_idle_motor_never_increases() -> None:
    # the tendon starts stretched and couples finger and motor; only friction acts on them
    st = replace(initial_finger_state(P), prox_rad=0.8, flex_rad=(0.1,) * 4,
                 motor_rad=(0.8 * P.r_base_m + 0.002 + P.tendon_slack_m) / P.r_motor_m)
    e, _ = _energy_trace(st, MotorCommand("force", force_units=0.0))
    # geometry is linearised within a step: allow round-off-level growth only
    assert np.all(np.diff(e) <= 1e-9 * e[0])
    assert e[-1] < e[0]


def test_tendon_never_pushes_and_goes_slack_when_released() -> None:
    res = run_experiment(ExperimentSpec("position", duration_s=20.0), P, NONE, NO_EFFECTS)
    force = res.recording.column("tendon_force_n")
    assert force.min() >= 0.0
    # drive the motor back past the rest slack: the tendon carries nothing
    st = initial_finger_state(P)
    for _ in range(2000):
        st = finger_step(st, MotorCommand("position", goal_rad=-0.5), P, NONE, NO_EFFECTS, 1e-3)
    assert st.tendon_force_n == 0.0
    assert st.prox_rad == 0.0


def test_joint_limits_hold_under_full_force_and_release() -> None:
    st = initial_finger_state(P)
    lo, hi = P.proximal_limits_rad
    slo, shi = P.flex_segment_limits_rad
    cmd = MotorCommand("force", force_units=1023.0)
    for _ in range(8000):
        st = finger_step(st, cmd, P, NONE, NO_EFFECTS, 1e-3)
        assert lo <= st.prox_rad <= hi
        assert all(slo <= s <= shi for s in st.flex_rad)
    assert st.prox_rad == hi  # driven onto the closed stop
    for _ in range(4000):
        st = finger_step(st, MotorCommand("position", goal_rad=-1.0), P, NONE, NO_EFFECTS, 1e-3)
        assert lo <= st.prox_rad <= hi
    assert st.prox_rad == lo


def _settle(joint_sp: float, effects=NO_EFFECTS, params=P, steps=4000):
    st = initial_finger_state(params)
    cmd = MotorCommand("position", goal_rad=JOINT_RATIO * joint_sp)
    for _ in range(steps):
        st = finger_step(st, cmd, params, NONE, effects, 1e-3)
    return st


@pytest.mark.parametrize("setpoint", [0.6, 0.9, 1.2])
def test_position_mode_offset_between_setpoint_and_proximal(setpoint: float) -> None:
    # report 3.1.1: the servo controls the motor angle, the proximal lags by ~0.25 rad
    st = _settle(setpoint)
    out = finger_outputs(st, P, NONE, NO_EFFECTS)
    assert out.joint_angle_rad == pytest.approx(setpoint, abs=0.06)
    assert 0.1 < setpoint - out.proximal_rad < 0.4
    assert out.distal_rad > 0.1  # the difference is taken up by the distal flexure


def test_load_spikes_on_setpoint_steps_and_goes_negative_on_decrease() -> None:
    rec = run_experiment(ExperimentSpec("position", duration_s=22.0), P, NONE,
                         NO_EFFECTS).recording
    t = rec.t_s
    sp = rec.column("setpoint_rad")
    load = rec.column("motor_load_units")
    steps = np.flatnonzero((np.abs(np.diff(sp)) > 0.1) & (t[1:] > 10.0)) + 1
    assert len(steps) >= 4
    for k in steps:
        window = load[k:k + 30]  # 0.3 s after the step
        before = load[k - 20:k - 1]
        jump = sp[k] - sp[k - 1]
        settled = np.abs(before).max()
        if jump > 0:
            assert window.max() > settled + 400.0 * min(jump, 1.0)
        else:
            assert window.min() < -200.0 * min(-jump, 1.0)  # the motor reverses: negative load
    # spike size grows with the step size
    jumps = np.abs(sp[steps] - sp[steps - 1])
    peaks = np.array([np.abs(load[k:k + 30]).max() for k in steps])
    order = np.argsort(jumps)
    assert peaks[order[0]] <= peaks[order[-1]]


def test_pressure_zero_until_contact_then_two_strong_neighbours_weak() -> None:
    rec = run_experiment(ExperimentSpec("grasp"), P, CYL, NO_EFFECTS).recording
    pr = np.column_stack([rec.column(f"pressure_{i}") for i in range(9)])
    touching = np.flatnonzero(pr.max(axis=1) > 0)
    assert len(touching) > 0
    first = touching[0]
    assert first > 10 and np.all(pr[:first] == 0.0)  # zero until contact
    # shortly after the first touch on the proximal link: two adjacent sensors dominate
    prox = pr[min(first + 20, len(pr) - 1), :5]
    order = np.argsort(prox)[::-1]
    strong = prox[order[:2]]
    weak = prox[order[2:]]
    assert abs(int(order[0]) - int(order[1])) == 1
    assert strong.min() > 3.0 * weak.max()
    assert weak.max() > 0.0  # neighbours see a little


def test_force_mode_is_slow_and_friction_limited() -> None:
    # Fig 4.15: 60 units moves the finger slowly towards equilibrium
    rec = run_experiment(ExperimentSpec("force-step", duration_s=30.0), P, NONE,
                         NO_EFFECTS).recording
    prox = rec.column("proximal_angle_rad")
    t = rec.t_s
    eq = (60.0 - P.motor_coulomb_units) / P.units_per_n * P.r_base_m / P.k_base_nm_per_rad \
        - P.base_preload_rad
    assert np.all(np.diff(prox) >= -1e-9)
    assert prox[t.searchsorted(5.0)] < 0.6 * eq
    assert prox[-1] < eq + 1e-6


def test_block_face_stops_the_finger_and_loads_the_touching_sensors() -> None:
    block = ContactObject(kind="block", y_m=0.03)
    st = initial_finger_state(P)
    cmd = MotorCommand("position", goal_rad=JOINT_RATIO * 1.5)
    for _ in range(3000):
        st = finger_step(st, cmd, P, block, NO_EFFECTS, 1e-3)
    out = finger_outputs(st, P, block, NO_EFFECTS)
    assert out.contact_points
    # nothing of the finger is deeper in the block than the contact compliance allows
    depth_max = 2.0 * out.tendon_force_n / block.stiffness_n_per_m + 0.002
    assert all(y - block.y_m < depth_max for _, y in out.points)
    assert max(out.pressure) > P.contact_threshold
    assert sum(out.contact) >= 1


def test_driver_command_delay_option_delays_motion_by_0_09_s() -> None:
    slow = replace(P, command_delay_s=0.09)
    cmd = MotorCommand("position", goal_rad=1.0)
    starts = []
    for params in (P, slow):
        st = initial_finger_state(params)
        k = 0
        while abs(st.motor_rad) < 1e-4:
            st = finger_step(st, cmd, params, NONE, NO_EFFECTS, 1e-3)
            k += 1
        starts.append(k * 1e-3)
    assert starts[1] - starts[0] == pytest.approx(0.09, abs=0.0015)


def test_pseudo_transformer_forces_are_2_fs_cos_theta() -> None:
    st = _settle(1.0)
    out = finger_outputs(st, P, NONE, NO_EFFECTS)
    fs = out.tendon_force_n
    assert fs > 0
    x1, x2, xc = (np.array(v) for v in out.tendon_points)
    # at X2 the string arrives from X1 and leaves to Xc: theta is half the angle between them
    a, b = x1 - x2, xc - x2
    cos_full = a @ b / np.linalg.norm(a) / np.linalg.norm(b)
    theta = 0.5 * np.arccos(np.clip(cos_full, -1, 1))
    assert out.tendon_point_forces_n[1] == pytest.approx(2 * fs * np.cos(theta), rel=1e-6)
    assert out.tendon_point_forces_n[2] == pytest.approx(fs)
