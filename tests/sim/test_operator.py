"""The virtual operator: grasp script, finger impedance against the displayed force, trigger."""

from __future__ import annotations

import pytest

from sim.operator import STYLES, VirtualOperator, operator_params, script_fraction
from teleop.config import load_config


def make(style: str = "relaxed", *extra: str) -> VirtualOperator:
    cfg = load_config(None, [f"master.virtual.style={style}", *extra])
    return VirtualOperator(cfg.master)


def hold_position(op: VirtualOperator, force_n: float, until_s: float = 3.0) -> float:
    op.apply_force(force_n)
    t, r = 0.0, None
    while t <= until_s + 1e-9:
        r = op.read(t)
        t += 0.001
    assert r is not None
    return r.grip_position_m


def test_script_close_hold_release() -> None:
    p = operator_params(load_config(None, []).master)
    assert script_fraction(p, 0.4) == 0.0
    assert script_fraction(p, 1.0) == pytest.approx(0.5)  # half way through the 1 s ramp
    assert script_fraction(p, 2.5) == 1.0
    assert script_fraction(p, 4.0) == pytest.approx(0.5)  # half way through the release
    assert script_fraction(p, 4.6) == 0.0
    assert script_fraction(p, 4.5 + 2.5) == 1.0  # repeats


def test_free_closing_reaches_full_travel_quantised() -> None:
    assert hold_position(make(), 0.0) == pytest.approx(0.025, abs=1e-5)
    x = hold_position(make(), 0.0, until_s=1.0)  # mid-ramp
    assert 0.005 < x < 0.02
    assert (x / 6e-6) == pytest.approx(round(x / 6e-6), abs=1e-6)


@pytest.mark.parametrize("style", ["hard", "relaxed", "soft"])
def test_finger_yields_like_its_spring(style: str) -> None:
    k, _ = STYLES[style]
    x = hold_position(make(style), 1.0)
    assert x == pytest.approx(0.025 - 1.0 / k, abs=2e-5)


def test_force_is_limited_to_the_trigger_rating() -> None:
    op = make("soft")
    op.apply_force(50.0)
    assert op.force_n == 8.0
    x = hold_position(op, 50.0)
    assert x == pytest.approx(max(0.0, 0.025 - 8.0 / STYLES["soft"][0]), abs=2e-5)


def test_script_starts_at_the_first_read() -> None:
    op = make()
    t0 = 1000.0
    for k in range(400):
        r = op.read(t0 + 0.001 * k)
    assert r.grip_position_m == 0.0  # still in the 0.5 s pause... then closing
    for k in range(1000, 2500):
        r = op.read(t0 + 0.001 * k)
    assert r.grip_position_m > 0.02


def test_explicit_stiffness_overrides_the_style() -> None:
    op = make("hard", "master.virtual.stiffness_n_per_m=200.0")
    assert op.params.stiffness_n_per_m == 200.0
    assert op.params.damping_n_s_per_m == STYLES["hard"][1]
