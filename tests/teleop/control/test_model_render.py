"""The master's rendering of the contact model: energy of a sampled spring against an
independently integrated trigger, phase-in limits, and the tank's hold.

The trigger here is integrated in this file (semi-implicit Euler at 20 kHz, the master's force
held for each 1 ms sample): the energy it exchanges is computed from its own motion, not from
the controller's ledger."""

from __future__ import annotations

from dataclasses import replace

import pytest

from teleop.config.control import ControllerConfig
from teleop.control import two_layer
from teleop.control.interface import control_params
from teleop.control.model_render import (
    RenderState,
    map_gain_rad_per_m,
    model_energy_j,
    model_force_n,
    step_render,
)
from teleop.messages import ForceCommand, Header

P = control_params(ControllerConfig())
DT = 0.001
# a stiff block: contact at 0.4 rad of set-point (3.3 mm of trigger), 40 N per rad
MODEL = (0.4, 40.0, 0.4, 40.0, 0.4, 40.0)


def command(model: tuple[float, ...], force_n: float = 0.0, total_j: float = 0.0) -> ForceCommand:
    return ForceCommand(header=Header(seq=1, t_s=0.0, energy_total_j=total_j), force_n=force_n,
                        model=model)


def operator_cycle(p, n_cycles: int = 5) -> tuple[float, float]:
    """A mass-spring operator (0.05 kg, 300 N/m towards 12 mm, no damping) squeezing the
    rendered block for a few cycles; returns (energy the trigger's motion took from the
    master's force, the master's ledger net port output)."""
    s = two_layer.init_master(p)
    q, v, f = 0.0, 0.0, 0.0
    sub = 20
    work_on_operator = 0.0
    for k in range(int(n_cycles * 0.4 / DT)):
        target = 0.012 if (k * DT) % 0.4 < 0.2 else 0.0
        for _ in range(sub):
            a = (300.0 * (target - q) - f) / 0.05
            v_new = v + a * DT / sub
            dq = v_new * DT / sub
            work_on_operator += -f * dq  # the display pushes against closing
            q += dq
            v = v_new
        s, out = two_layer.step_master(s, p, q, command(MODEL), DT)
        f = out.force_n
    led = s.ledger
    return work_on_operator, led.port_out_j - led.port_in_j


def test_the_rendered_spring_takes_back_what_it_gives_and_its_damping_keeps_it_passive() -> None:
    p = replace(P, tlc_gain=0.0)  # no level controller: the rendering alone
    given, ledger_net = operator_cycle(p)
    assert given <= 1e-6  # over whole cycles the operator got back no more than he put in
    assert ledger_net == pytest.approx(given, abs=2e-4)  # the ledger sees the same port work
    # the mutant: no rendered damping; the sampled spring then gives energy away
    undamped = replace(p, contact_model=replace(p.contact_model, damping_periods=0.0))
    given0, _ = operator_cycle(undamped)
    assert given0 > given


def test_a_model_update_is_phased_in_at_the_rate_limit_and_within_the_tank() -> None:
    q = 0.0045  # 0.54 rad: in contact, 5.6 N
    r = RenderState()
    rate = 40.0
    forces = []
    for _ in range(400):
        r = step_render(r, P, MODEL, q, 10.0, rate, DT)
        forces.append(model_force_n(r, P, q))
    steps = [b - a for a, b in zip([0.0] + forces, forces, strict=False)]
    assert max(abs(d) for d in steps) <= rate * DT * (1 + 1e-6)
    want = min(40.0 * (q * map_gain_rad_per_m(P) - 0.4), P.force_max_n)
    assert forces[-1] == pytest.approx(want, rel=0.01)
    assert r.phase == pytest.approx(1.0, abs=0.01)
    # an empty tank: an update that raises the stored energy waits; one that lowers it does not
    r0 = RenderState()
    assert step_render(r0, P, MODEL, q, 0.0, rate, DT).stiffness_n_per_rad == (0.0, 0.0, 0.0)
    softer = step_render(r, P, (0.4, 10.0) * 3, q, 0.0, rate, DT)
    assert model_energy_j(softer, P, q) < model_energy_j(r, P, q)


def test_out_of_contact_the_model_comes_in_at_once_and_the_fallback_fades_with_it() -> None:
    r = step_render(RenderState(), P, MODEL, 0.001, 10.0, 40.0, DT)
    assert r.stiffness_n_per_rad == (40.0, 40.0, 40.0) and r.phase == 1.0
    s = two_layer.init_master(P)
    s, out = two_layer.step_master(s, P, 0.001, command(MODEL, force_n=3.0), DT)
    assert out.force_n == pytest.approx(0.0, abs=1e-9)  # the delayed 3 N is gone with the model
    s2, out2 = two_layer.step_master(two_layer.init_master(P), P, 0.001,
                                     command((0.0,) * 6, force_n=3.0), DT)
    assert out2.force_n == pytest.approx(3.0)  # no model: the delayed force, as before


def test_the_master_tank_keeps_the_rendered_energy_before_sending_quanta() -> None:
    p = replace(P, initial_j=0.3, reserve_j=0.01, transfer_fraction=1.0, tlc_gain=0.0)
    s = two_layer.init_master(p)
    q = 0.0
    for _ in range(3000):  # squeeze into the block and hold
        q = min(q + 0.00002, 0.010)
        s, out = two_layer.step_master(s, p, q, command(MODEL), 0.001)
    held = model_energy_j(s.render, p, q)
    g = map_gain_rad_per_m(p)
    # one finger's ramp up to the trigger's 8 N, then flat
    th, th8 = q * g, 0.4 + p.force_max_n / 40.0
    assert held == pytest.approx((0.5 * 8.0 * (th8 - 0.4) + 8.0 * (th - th8)) / g, rel=0.01)
    # what the operator put into the spring is still in the tank, above its reserve
    assert s.ledger.port_in_j == pytest.approx(held, rel=0.05)
    assert s.ledger.tank_j >= 0.99 * held + p.reserve_j
    # so the release is paid without the limiter: the operator gets the spring back
    for _ in range(600):
        q = max(q - 0.00002, 0.0)
        s, out = two_layer.step_master(s, p, q, command(MODEL), 0.001)
        assert not out.limited
    assert s.ledger.port_out_j == pytest.approx(s.ledger.port_in_j, rel=0.05)


def test_a_withdrawn_model_ramps_out_unless_the_link_is_cut() -> None:
    q = 0.0045
    r = RenderState()
    for _ in range(400):
        r = step_render(r, P, MODEL, q, 10.0, 40.0, DT)
    f = model_force_n(r, P, q)
    assert f > 5.0
    cut = step_render(r, P, (0.0,) * 6, q, 10.0, 40.0, DT, cut=True)  # a watchdog cut
    assert model_force_n(cut, P, q) == 0.0 and cut.phase == 0.0
    gone = step_render(r, P, (0.0,) * 6, q, 10.0, 40.0, DT)  # the hand withdrew it
    assert model_force_n(gone, P, q) == pytest.approx(f - 40.0 * DT)
    half = step_render(r, P, (0.4, 20.0) * 3, q, 10.0, 40.0, DT)  # a watchdog ramp step
    assert model_force_n(half, P, q) == pytest.approx(f - 40.0 * DT)


def test_a_dropped_estimate_hands_over_to_the_delayed_force_without_a_step() -> None:
    """The hand drops a diverged model while the delayed measured force says 3 N: the
    displayed force falls at most the drop rate limit per sample (never below the delayed
    force) and ends at the delayed force."""
    p = replace(P, tlc_gain=0.0)
    s = two_layer.init_master(p)
    q = 0.0045
    for _ in range(600):
        s, out = two_layer.step_master(s, p, q, command(MODEL, force_n=3.0), DT)
    before = out.force_n
    assert before > 5.0
    full = s
    forces = [before]
    for _ in range(600):
        s, out = two_layer.step_master(s, p, q, command((0.0,) * 6, force_n=3.0), DT)
        forces.append(out.force_n)
    drop = p.contact_model.force_drop_rate_n_per_s
    steps = [b - a for a, b in zip(forces, forces[1:], strict=False)]
    assert max(steps) <= 1e-9 and min(steps) >= -drop * DT - 1e-9
    assert min(forces) >= 3.0 - 0.05
    assert forces[-1] == pytest.approx(3.0, abs=0.05)
    # the same command zeroed by a watchdog: the force goes at once
    _, cut = two_layer.step_master(full, p, q, command((0.0,) * 6, force_n=0.0), DT)
    assert cut.force_n == 0.0


def test_the_written_out_default_force_is_the_general_one_bit_for_bit() -> None:
    """``_force_at``'s three-finger ``max`` path against ``_force_of`` (the reference): the
    same float, signed zeros and NaN included."""
    import math
    import random
    import struct

    from teleop.control.model_render import RenderState, _force_at, _force_of, _terms

    rng = random.Random(7)
    odd = (0.0, -0.0, math.nan, math.inf, -math.inf, 1e-300)

    def v(scale: float) -> float:
        return rng.choice(odd) if rng.random() < 0.2 else scale * rng.uniform(-1.0, 2.0)

    for _ in range(3000):
        r = RenderState(contact_rad=(v(1), v(1), v(1)), stiffness_n_per_rad=(v(50), v(50), v(50)))
        th = v(1)
        want = _force_of(_terms(r, P), P.force_combine, P.force_max_n, th)
        assert struct.pack("<d", _force_at(r, P, th)) == struct.pack("<d", want)


def test_the_written_out_default_energy_is_the_general_one_bit_for_bit() -> None:
    """``_model_energy_j``'s three-finger ``max`` path (no list of forces) against the
    trapezoids over ``_force_of`` written here, added left to right: the same float."""
    import random
    import struct

    from teleop.control.model_render import (
        _ENVELOPE_STEPS,
        RenderState,
        _force_of,
        _model_energy_j,
        _terms,
        map_gain_rad_per_m,
        setpoint_rad,
    )

    def reference(r: RenderState, q: float) -> float:
        on = [i for i in range(3) if r.stiffness_n_per_rad[i] > 0.0]
        if not on:
            return 0.0
        t_end, t0 = setpoint_rad(P, q), min(r.contact_rad[i] for i in on)
        if t_end <= t0:
            return 0.0
        h = (t_end - t0) / _ENVELOPE_STEPS
        f = [_force_of(_terms(r, P), "max", P.force_max_n, t0 + j * h)
             for j in range(_ENVELOPE_STEPS + 1)]
        total = 0.0
        for x in f:
            total += x
        return h * (total - 0.5 * (f[0] + f[-1])) / map_gain_rad_per_m(P)

    assert P.force_combine == "max" and all(P.finger_enable)
    rng = random.Random(11)

    def k() -> float:
        return 0.0 if rng.random() < 0.2 else rng.uniform(0.0, 200.0)

    checked = 0
    for _ in range(2000):
        r = RenderState(contact_rad=(rng.uniform(0, 2), rng.uniform(0, 2), rng.uniform(0, 2)),
                        stiffness_n_per_rad=(k(), k(), k()))
        q = rng.uniform(-0.005, P.trigger_travel_m * 1.2)
        want = reference(r, q)
        checked += want > 0.0
        assert struct.pack("<d", _model_energy_j(r, P, q)) == struct.pack("<d", want)
    assert checked > 500  # most draws store energy: the sums are exercised


@pytest.mark.parametrize("raise_it", [True, False])
def test_a_model_update_raises_the_force_at_the_rise_rate_and_lowers_it_at_the_drop_rate(
        raise_it: bool) -> None:
    """A rendered block at 4.5 mm of trigger (5.6 N), then the model moved 0.05 rad in (more
    force) or out (less): the rendered force moves by the rise limit per sample going up and
    by the (faster) drop limit going down, and reaches the new model's force."""
    cm = P.contact_model
    assert cm.force_drop_rate_n_per_s > cm.force_rate_n_per_s
    q, budget = 0.0045, 1e3
    r = RenderState()
    for _ in range(1000):  # the model phased in in full
        r = step_render(r, P, MODEL, q, budget, cm.force_rate_n_per_s, DT, False,
                        cm.force_drop_rate_n_per_s)
    f0 = model_force_n(r, P, q)
    assert r.stiffness_n_per_rad == (40.0,) * 3 and f0 == pytest.approx(5.6)
    c = 0.35 if raise_it else 0.45  # 7.6 N or 3.6 N (under the 8 N clip): linear in c
    moved = (c, 40.0) * 3
    forces = [f0]
    for _ in range(400):
        r = step_render(r, P, moved, q, budget, cm.force_rate_n_per_s, DT, False,
                        cm.force_drop_rate_n_per_s)
        forces.append(model_force_n(r, P, q))
    steps = [b - a for a, b in zip(forces, forces[1:], strict=False)]
    target = model_force_n(RenderState(contact_rad=(c,) * 3, stiffness_n_per_rad=(40.0,) * 3),
                           P, q)
    assert forces[-1] == pytest.approx(target, abs=1e-6)
    if raise_it:
        assert min(steps) >= -1e-12
        assert max(steps) == pytest.approx(cm.force_rate_n_per_s * DT, rel=1e-6)
    else:
        assert max(steps) <= 1e-12
        assert min(steps) == pytest.approx(-cm.force_drop_rate_n_per_s * DT, rel=1e-6)
