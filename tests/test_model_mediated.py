"""Model-mediated two-layer in lockstep (issue 15): the grasp felt across delay, on soft and
stiff objects, and an object that is removed or moved mid-grasp.

The three services run on the in-process bus with the simulated hand; "true" force is the
force map applied to the pressures the simulated hand really reads (delayed by the backward
path), as the sweep's felt/true column (``teleop.analysis.stability``)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace

import numpy as np
import pytest

from services.lockstep import LockstepContext, run_lockstep
from sim.contact import NO_OBJECT
from teleop.analysis.grasps import format_grasps
from teleop.analysis.stability import felt_true_force_ratio, tracking_hold_rad
from teleop.analysis.sweep_objects import with_object
from teleop.analysis.sweep_signals import signals_from_lockstep
from teleop.config import TeleopConfig, load_config
from tests.job_pool import JobPool, lockstep
from tests.services.lockstep_grasps import grasps_of

#: the sweep's scenario: close to 60 % of the travel over 1 s, then hold
HOLD = ["master.virtual.closed_fraction=0.6", "master.virtual.repeat=false",
        "master.virtual.hold_s=100.0"]


def cfg_for(delay_s: float, loss: float = 0.0, obj: str | None = None, extra: tuple = ()):
    cfg = load_config(None, [*HOLD, f"links.master_controller.delay_s={delay_s}",
                             f"links.master_controller.loss={loss}",
                             f"links.controller_hand.loss={loss}", *extra])
    return with_object(cfg, obj) if obj else cfg


FELT = [(0.2, 0.2, 0.8, "stiff-cylinder"), (0.2, 0.2, 0.8, "soft-cylinder"),
        (0.2, 0.2, 0.8, "block"), (1.0, 0.2, 0.6, "stiff-cylinder"),
        (1.0, 0.2, 0.6, "soft-cylinder"), (1.0, 0.2, 0.6, "block")]


def repeated_cfg(delay_s: float) -> TeleopConfig:
    return load_config(None, [f"links.master_controller.delay_s={delay_s}",
                              "links.master_controller.loss=0.2",
                              "links.controller_hand.loss=0.2"])


@pytest.fixture(scope="module")
def runs() -> Iterator[JobPool]:
    """Every hook-free run of this module, started together on two processes (the same
    ``run_lockstep(cfg, seconds, seed=...)`` each test made itself, computed side by side;
    the two hooked runs below run here meanwhile)."""
    jobs: dict = {}
    for d, loss, _, obj in FELT:  # in the order the tests ask for them
        direct = cfg_for(0.0, 0.0, obj, ("controller.kind=direct",))
        jobs.setdefault(("direct", obj), (lockstep, (direct, 6.0, 3)))
        jobs[("felt", d, loss, obj)] = (lockstep, (cfg_for(d, loss, obj), 6.0 + 4.0 * d, 3))
    jobs["no-model"] = (lockstep, (cfg_for(0.2, 0.2, "stiff-cylinder",
                                           ("controller.contact_model.enabled=false",)),
                                   6.8, 3))
    jobs |= {("repeated", d): (lockstep, (repeated_cfg(d), 40.0, 2)) for d in (0.2, 1.0)}
    with JobPool(jobs) as pool:
        yield pool


def _direct_hold_rad_at_zero_delay(runs: JobPool, obj: str) -> float:
    """Closure error in the steady hold of plain position-force control with no delay, the
    same operator and object: the servo's own squeeze, the floor any controller shares."""
    cfg = cfg_for(0.0, 0.0, obj, ("controller.kind=direct",))
    return tracking_hold_rad(signals_from_lockstep(runs.result(("direct", obj)), cfg))


@pytest.mark.parametrize("delay_s,loss,floor,obj", FELT)
def test_the_steady_grasp_is_felt_across_delay(runs: JobPool, delay_s: float, loss: float,
                                                floor: float, obj: str) -> None:
    cfg = cfg_for(delay_s, loss, obj)
    r = runs.result(("felt", delay_s, loss, obj))
    sig = signals_from_lockstep(r, cfg)
    ratio = felt_true_force_ratio(sig)
    assert ratio >= floor, f"{obj} at {delay_s} s: felt/true {ratio:.2f}"
    # issue 15: the hand's closure within 0.1 rad of the command once the delay has passed;
    # in contact the gap is the squeeze the position servo needs for the grasp force, deepest
    # on the 5000 N/m block: there the bound is what `direct` itself leaves at zero delay
    # (0.106 rad in this scenario), plus 10 % - the delay adds no closure error of its own
    track = tracking_hold_rad(sig)
    bound = max(0.1, 1.1 * _direct_hold_rad_at_zero_delay(runs, obj))
    assert track <= bound, f"{obj} at {delay_s} s: closure {track:.3f} rad from the command"
    # the model, not the delayed force, is what is felt in the steady grasp
    late = r.t_s > r.t_s[-1] - 1.0
    assert np.all(r.displayed_force_n[late] > 1.0)


def test_without_the_model_the_grasp_is_not_felt_at_200_ms(runs: JobPool) -> None:
    """The comparison the floors above are about: the delayed force alone, gain-scheduled."""
    cfg = cfg_for(0.2, 0.2, "stiff-cylinder", ("controller.contact_model.enabled=false",))
    r = runs.result("no-model")
    assert felt_true_force_ratio(signals_from_lockstep(r, cfg)) < 0.5


def _with_hook(cfg, t_at: float, change):
    def hook(t_s: float, ctx: LockstepContext) -> None:
        if t_s >= t_at and ctx.hand is not None and not getattr(hook, "done", False):
            change(ctx.hand.backend)
            hook.done = True  # type: ignore[attr-defined]
    return hook


def test_an_object_removed_mid_grasp_is_felt_gone_within_a_round_trip() -> None:
    delay = 0.2
    cfg = cfg_for(delay)
    t_rm = 4.0
    r = run_lockstep(cfg, 6.0, seed=1,
                     hook=_with_hook(cfg, t_rm, lambda hand: setattr(hand, "obj", NO_OBJECT)))
    t, f = r.t_s, r.displayed_force_n
    assert f[(t > t_rm - 0.5) & (t < t_rm)].min() > 3.0  # a real grasp before
    # one round trip (0.4 s), a hand period and the displayed-force filter
    gone = t > t_rm + 2 * delay + 0.1
    assert np.abs(f[gone]).max() < 0.3
    assert r.pressure[gone].max() < 20  # the hand found nothing to press either


def test_an_object_moved_mid_grasp_is_re_measured() -> None:
    cfg = cfg_for(0.2)
    t_mv = 4.0

    def move(hand) -> None:  # 5 mm further away across the finger: a later contact
        hand.obj = replace(hand.obj, y_m=hand.obj.y_m + 0.005)

    r = run_lockstep(cfg, 9.0, seed=1, hook=_with_hook(cfg, t_mv, move))
    sig = signals_from_lockstep(r, cfg)
    t = r.t_s
    late = (t > t_mv + 3.0)
    true = np.interp(t - 0.2, t, sig.force_measured_n)[late]
    felt = r.displayed_force_n[late]
    assert float(np.mean(true)) > 2.0  # still grasping
    assert float(np.mean(felt) / np.mean(true)) == pytest.approx(1.0, abs=0.2)


@pytest.mark.parametrize("delay_s", [0.2, 1.0])
def test_repeated_grasps_under_delay_and_loss_all_hold_up_against_the_first(
        runs: JobPool, delay_s: float) -> None:
    """The virtual operator's repeated grasps (goal 1 of issue 13, short): with 20 % loss on
    both links every grasp reaches 90 % of the first's peak pressure and closure; the first
    no longer overshoots (the touch is capped until the master has seen its model)."""
    cfg = repeated_cfg(delay_s)
    r = runs.result(("repeated", delay_s))
    g = grasps_of(r, cfg)
    assert len(g.grasps) >= 7
    assert g.min_pressure_ratio >= 0.9, format_grasps(g)
    assert g.min_closure_ratio >= 0.9, format_grasps(g)
    assert g.grasps[0].peak_pressure < 1000  # not the 1,600-3,000 overshoot of before
