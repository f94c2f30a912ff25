"""The three service shells in lockstep on the in-process bus (fake hand, virtual operator)."""

from __future__ import annotations

import numpy as np
import pytest
from _svc_fakes import FakeHand

from services.lockstep import LockstepResult, run_lockstep
from teleop.config import load_config

CONTACT_RAD = 1.2


def run(overrides: list[str] | None = None, duration_s: float = 4.0, seed: int = 3
        ) -> LockstepResult:
    cfg = load_config(None, ["master.virtual.repeat=false", *(overrides or [])])
    return run_lockstep(cfg, duration_s, seed=seed, hand=FakeHand(contact_rad=CONTACT_RAD))


@pytest.fixture(scope="module")
def base() -> LockstepResult:
    return run()


def test_one_row_per_master_tick(base: LockstepResult) -> None:
    assert base.t_s.size == 4001
    assert np.allclose(np.diff(base.t_s), 1e-3)
    assert base.proximal_rad.shape == (4001, 3) and base.pressure.shape == (4001, 27)


def test_fingers_close_on_the_object_when_the_trigger_closes(base: LockstepResult) -> None:
    hold = (base.t_s > 2.0) & (base.t_s < 3.4)  # script: close 0.5-1.5 s, hold to 3.5 s
    assert base.trigger_position_m[base.t_s < 0.5].max() == 0.0
    assert base.trigger_position_m[hold].min() > 0.015
    # the fingers reach the object and stop there
    assert np.all(np.abs(base.proximal_rad[hold] - CONTACT_RAD) < 0.02)
    assert base.pressure[hold].max() > 20.0


def test_operator_feels_the_grasp(base: LockstepResult) -> None:
    hold = (base.t_s > 2.0) & (base.t_s < 3.4)
    free = base.t_s < 0.5
    assert np.all(base.displayed_force_n[hold] > 0.5)
    assert np.all(np.abs(base.displayed_force_n[free]) < 1e-6)
    # the virtual operator's finger yields under the displayed force: trigger short of 25 mm
    assert base.trigger_position_m[hold].max() < 0.025


def test_energy_balance_holds_at_every_sample(base: LockstepResult) -> None:
    assert base.initial_j > 0
    assert np.all(base.energy_margin_j >= -1e-9)
    assert base.energy_generated_j == 0.0
    assert np.all(base.received_j <= base.sent_j + 1e-12)  # the links never create energy
    for tank in (base.master_tank_j, base.hand_tank_j, base.controller_store_j):
        assert np.nanmin(tank) >= -1e-12


def test_same_seed_same_run_and_different_seed_differs() -> None:
    over = ["links.master_controller.jitter=uniform", "links.master_controller.jitter_s=0.01",
            "links.master_controller.loss=0.2"]
    a, b, c = run(over, 1.5, seed=1), run(over, 1.5, seed=1), run(over, 1.5, seed=2)
    assert np.array_equal(a.displayed_force_n, b.displayed_force_n)
    assert np.array_equal(a.delay_master_to_controller_s, b.delay_master_to_controller_s,
                          equal_nan=True)
    assert not np.array_equal(a.delay_master_to_controller_s, c.delay_master_to_controller_s,
                              equal_nan=True)


def test_achieved_delays_and_drops_follow_the_links() -> None:
    r = run(["links.master_controller.delay_s=0.05", "links.controller_hand.delay_s=0.02",
             "links.controller_hand.loss=0.3"], 1.0)
    assert np.nanmedian(r.delay_master_to_controller_s) == pytest.approx(0.05, abs=1e-9)
    assert np.nanmedian(r.delay_controller_to_master_s) == pytest.approx(0.05, abs=1e-9)
    assert np.nanmedian(r.delay_hand_to_controller_s) == pytest.approx(0.02, abs=1e-9)
    # the hand reads ~25 commands per tick; its latest command is 20 ms old
    assert np.nanmedian(r.delay_controller_to_hand_s) == pytest.approx(0.02, abs=1e-9)
    assert r.dropped_hand_command[-1] > 0 and r.dropped_master_state[-1] == 0
    assert 0.2 < r.dropped_hand_command[-1] / 1000 < 0.4


def test_runs_faster_than_real_time() -> None:
    import time

    t0 = time.perf_counter()
    run(duration_s=2.0)
    assert time.perf_counter() - t0 < 2.0


def test_a_lockstep_run_can_be_logged_to_the_dashboard(tmp_path) -> None:  # noqa: ANN001
    from rerun.chunk import RrdReader

    from teleop.viz.dashboard import DASHBOARD_PATHS, PHYSICS_PATHS, open_stream

    out = tmp_path / "lockstep.rrd"
    rec = open_stream("lockstep-test", "save", path=out)
    cfg = load_config(None, ["master.virtual.repeat=false", "master.virtual.close_s=0.0",
                             "master.virtual.ramp_s=0.3"])
    run_lockstep(cfg, 1.0, seed=1, hand=FakeHand(contact_rad=0.5), rec=rec)
    rec.flush()
    rec.disconnect()
    found = {c.entity_path.lstrip("/") for c in RrdReader(out).stream()
             if not c.is_static and c.num_rows > 0}
    assert not [p for p in DASHBOARD_PATHS if p not in found]
    # the virtual operator's physics beside its books; the fake hand has none
    assert [p for p in PHYSICS_PATHS if p in found] == ["master/physics_delivered_j",
                                                        "master/physics_taken_j"]


def test_default_backends_grasp_the_object_passively() -> None:
    """Virtual operator + simulated hand (sim.sim_hand) with the default config."""
    cfg = load_config(None, ["master.virtual.repeat=false"])
    r = run_lockstep(cfg, 3.0, seed=0)
    before = r.t_s < 0.5
    closed = r.t_s > 2.0
    assert r.pressure[before].max() < 20.0 < r.pressure[closed].max()
    flex = r.proximal_rad + r.distal_rad
    assert flex[closed].mean() > flex[before].mean() + 0.1
    assert np.median(r.displayed_force_n[closed]) > 0.3
    assert r.energy_generated_j == 0.0 and np.all(r.energy_margin_j >= -1e-9)


def test_controller_death_mid_grasp_hand_holds_and_force_ramps_out() -> None:
    from services.lockstep import LockstepContext

    def kill_at_2s(t: float, ctx: LockstepContext) -> None:
        if t >= 2.0 and ctx.controller is not None:
            ctx.kill_controller()

    cfg = load_config(None, ["master.virtual.repeat=false"])
    r = run_lockstep(cfg, 3.0, seed=1, hand=FakeHand(contact_rad=CONTACT_RAD), hook=kill_at_2s)
    after = r.t_s > 2.05
    # the hand holds where it was (on the object) instead of opening or moving on
    held = r.hand_setpoint_rad[after]
    assert np.ptp(held, axis=0).max() < 1e-9
    assert np.all(np.abs(r.proximal_rad[after] - CONTACT_RAD) < 0.02)
    # the grasp force shown to the operator goes at once (liveliness lost); only the tank
    # level controller's damping of the operator's motion may remain
    assert r.master_force_desired_n[r.t_s < 2.0][-1] > 0.5
    assert np.all(r.master_force_desired_n[r.t_s > 2.01] == 0.0)
    assert r.watchdog_trips >= 2
    assert np.all(r.energy_margin_j >= -1e-9)


def test_a_run_stopped_early_is_the_same_run_cut_at_the_time_reached(
        base: LockstepResult) -> None:
    """``stop`` (a command's Ctrl-C) ends the run at a whole master row: the result is the
    uninterrupted run's first rows, every series the same length, ``duration_s`` the time
    reached."""
    asked = [0]

    def stop() -> bool:
        asked[0] += 1
        return asked[0] >= 1500

    cfg = load_config(None, ["master.virtual.repeat=false"])
    cut = run_lockstep(cfg, 4.0, seed=3, hand=FakeHand(contact_rad=CONTACT_RAD), stop=stop)
    assert cut.t_s.size == 1500 and cut.duration_s == pytest.approx(1.499)
    for name in ("displayed_force_n", "proximal_rad", "pressure", "hand_tank_j",
                 "audit_operator_delivered_j", "delay_controller_to_hand_s"):
        a, b = getattr(cut, name), getattr(base, name)
        assert a.shape[0] == 1500 and np.array_equal(a, b[:1500], equal_nan=True), name
