"""Mutation check: each breakage of the passivity layers must make a physics-judged check fail.

Every check is judged from physics the test computes itself, never from the controllers'
ledgers: the operator-port work of a scripted trigger (``run_master_rig``), the energy audit
of the closed-loop harness (``run_loop``: work on the operator and on the spring wall), or the
physical audit of a lockstep run with the simulated operator and hand
(``LockstepResult.audit_margin_j``, from ``sim.operator``/``sim.audit``).  Tanks are small
(0.05-0.1 J) so the bound bites.  Each check passes on the unpatched code
(``test_check_passes_unpatched``) and fails for its mutants (``test_mutant_is_caught``).

Each mutant ``apply(mp)`` patches the code with a pytest ``MonkeyPatch``.  Functions are
imported by name into :mod:`teleop.control.two_layer`, so they are patched there; whole
steps are replaced in the registry (``CONTROLLERS``), where the harness and the services
look the suite up.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from _ctl_harness import Scenario, audit_failure, initial_tank_j, run_loop, run_master_rig

from services.lockstep import LockstepContext, run_lockstep
from teleop.config import load_config
from teleop.config.control import ControllerConfig
from teleop.control import two_layer, two_layer_hand
from teleop.control.energy_channel import TotalReceiver
from teleop.control.energy_tank import port_work_j
from teleop.control.interface import ControlParams, control_params
from teleop.control.model_render import RenderState, model_force_n
from teleop.control.passivity_layer import dissipation_lower_bound_j, spring_energy_j
from teleop.control.registry import CONTROLLERS
from teleop.transport import bus
from tests.teleop.control.two_layer_parts import patch_sides

Mutant = Callable[[pytest.MonkeyPatch], None]

#: energy the "store below zero" controller forwards every sample beyond what it holds
OVERDRAFT_J = 2e-4


def _replace_suite(mp: pytest.MonkeyPatch, **steps: Callable[..., Any]) -> None:
    mp.setitem(CONTROLLERS, "two-layer", replace(CONTROLLERS["two-layer"], **steps))


def port_work_sign_flipped(mp: pytest.MonkeyPatch) -> None:
    """The master's tank credits the work it does on the operator instead of paying it."""
    patch_sides(mp, "port_work_j", lambda f, dq: -port_work_j(f, dq))


def dissipation_over_credited(mp: pytest.MonkeyPatch) -> None:
    """The hand's tank is credited 50x the servo damping's dissipation lower bound."""
    patch_sides(mp, "dissipation_lower_bound_j",
               lambda x, xp, b, dt: 50.0 * dissipation_lower_bound_j(x, xp, b, dt))


def franken_limiter_removed(mp: pytest.MonkeyPatch) -> None:
    """The master's desired force is not limited against ``H - H_min``."""
    patch_sides(mp, "franken_limit", lambda f, v, budget, dt: f)


def guard_removed(mp: pytest.MonkeyPatch) -> None:
    """The master's hard guard ``|F| <= H / (max(v_max, |v|) T)`` is gone."""
    patch_sides(mp, "guard_force", lambda f, tank, v, vmax, dt: f)


def setpoint_modulation_skipped(mp: pytest.MonkeyPatch) -> None:
    """The hand applies the desired set-point whatever it costs (its tank still pays)."""
    def project(desired: Any, previous: Any, x: Any, budget: float, k: float,
                tau: float = math.inf) -> tuple[Any, float, bool]:
        dp = spring_energy_j(desired, x, k, tau) - spring_energy_j(previous, x, k, tau)
        return desired, dp, False
    patch_sides(mp, "pspm_project", project)


def quanta_as_increments(mp: pytest.MonkeyPatch) -> None:
    """Every sender puts its per-sample quantum on the message instead of the running total,
    and every receiver credits the value it finds in a message."""
    suite = CONTROLLERS["two-layer"]

    def credit(rx: TotalReceiver, total: float | None) -> tuple[TotalReceiver, float]:
        if total is None or not math.isfinite(total) or total <= 0.0:
            return rx, 0.0
        return rx, total

    def step_master(s: Any, *a: Any) -> Any:
        ns, out = suite.step_master(s, *a)
        return ns, replace(out, energy_total_j=ns.ledger.sent_j - s.ledger.sent_j)

    def step_controller(s: Any, *a: Any) -> Any:
        ns, co = suite.step_controller(s, *a)
        fc, hc = co.force_command, co.hand_command
        fc = replace(fc, header=replace(fc.header, energy_total_j=ns.sent_to_master_j
                                        - s.sent_to_master_j))
        hc = replace(hc, header=replace(hc.header, energy_total_j=ns.sent_to_hand_j
                                        - s.sent_to_hand_j))
        return ns, replace(co, force_command=fc, hand_command=hc)

    def step_hand(s: Any, *a: Any) -> Any:
        ns, out = suite.step_hand(s, *a)
        return ns, replace(out, energy_total_j=ns.ledger.sent_j - s.ledger.sent_j)

    patch_sides(mp, "receive_total", credit)
    _replace_suite(mp, step_master=step_master, step_controller=step_controller,
                   step_hand=step_hand)


def store_below_zero(mp: pytest.MonkeyPatch) -> None:
    """The controller forwards ``OVERDRAFT_J`` per sample more than its store holds (split
    as usual), so its store goes below zero; its books still balance."""
    suite = CONTROLLERS["two-layer"]

    def step_controller(s: Any, p: Any, *a: Any) -> Any:
        ns, co = suite.step_controller(s, p, *a)
        to_h = p.controller_split * OVERDRAFT_J
        to_m = (OVERDRAFT_J - to_h) / p.energy_scale
        led = replace(ns.ledger, tank_j=ns.ledger.tank_j - OVERDRAFT_J,
                      sent_j=ns.ledger.sent_j + OVERDRAFT_J)
        ns = replace(ns, ledger=led, sent_to_master_j=ns.sent_to_master_j + to_m,
                     sent_to_hand_j=ns.sent_to_hand_j + to_h)
        fc, hc = co.force_command, co.hand_command
        fc = replace(fc, header=replace(fc.header, energy_total_j=ns.sent_to_master_j))
        hc = replace(hc, header=replace(hc.header, energy_total_j=ns.sent_to_hand_j))
        return ns, replace(co, force_command=fc, hand_command=hc, ledger=led)

    _replace_suite(mp, step_controller=step_controller)


def epoch_credited_on_restart(mp: pytest.MonkeyPatch) -> None:
    """Every new sender epoch (a restart on either side) is credited from zero: the first
    total a (re)started receiver sees counts in full, as if it were the sender's first."""
    mp.setattr(bus, "FIRST_SEQ", 2 ** 62)


def model_rendered_outside_tank(mp: pytest.MonkeyPatch) -> None:
    """The master displays the received contact model in full, after its passivity layer
    (no phase-in against the tank, no limiter, no guard)."""
    step = two_layer.step_master

    def step_master(s: Any, p: ControlParams, q: float, command: Any, dt: float) -> Any:
        ns, out = step(s, p, q, command, dt)
        if command is None:
            return ns, out
        m = command.model
        full = model_force_n(RenderState(contact_rad=(m[0], m[2], m[4]),
                                         stiffness_n_per_rad=(m[1], m[3], m[5])), p, q)
        f = max(out.force_n, full)
        return replace(ns, force_prev_n=f), replace(out, force_n=f)
    _replace_suite(mp, step_master=step_master)


def refund_in_contact(mp: pytest.MonkeyPatch) -> None:
    """The free-motion refund is paid whatever the tactile cells say (contact ignored)."""
    patch_sides(mp, "finger_contacts", lambda fingers: (False, False, False))


def two_sided_damping_credit(mp: pytest.MonkeyPatch) -> None:
    """Opening motion is credited too, although the one-sided servo potential never charged
    the servo's push that drives it."""
    def credit(x: Any, xp: Any, b: float, dt: float) -> float:
        return b * sum((u - v) ** 2 for u, v in zip(x, xp, strict=True)) / dt if dt > 0 else 0.0
    patch_sides(mp, "dissipation_lower_bound_j", credit)


def object_work_sign_flipped(mp: pytest.MonkeyPatch) -> None:
    """Environment-port hand: work the pads do on the object is credited, work the object
    gives back charged (the two estimates swapped)."""
    track = two_layer_hand.track_fingers

    def swapped(model: Any, prev: Any, fingers: Any) -> Any:
        tracks, works = track(model, prev, fingers)
        return tracks, tuple((i, o) for o, i in works)
    patch_sides(mp, "track_fingers", swapped)


def object_work_not_charged(mp: pytest.MonkeyPatch) -> None:
    """Environment-port hand: the tank is never charged for the work on the object."""
    track = two_layer_hand.track_fingers

    def free(model: Any, prev: Any, fingers: Any) -> Any:
        tracks, works = track(model, prev, fingers)
        return tracks, tuple((0.0, i) for _, i in works)
    patch_sides(mp, "track_fingers", free)


def reservation_ignored(mp: pytest.MonkeyPatch) -> None:
    """Environment-port hand: the set-point goes where it is asked, whatever the servo
    potential and tendon stretch it builds up (the tank still pays the object work)."""
    patch_sides(mp, "reserve_project", lambda want, x, budget, k, tmax, kt: (want, False))


MUTANTS: dict[str, Mutant] = {
    "port_work_sign_flipped": port_work_sign_flipped,
    "dissipation_over_credited_x50": dissipation_over_credited,
    "franken_limiter_removed": franken_limiter_removed,
    "guard_removed": guard_removed,
    "quanta_as_increments": quanta_as_increments,
    "store_below_zero": store_below_zero,
    "setpoint_modulation_skipped": setpoint_modulation_skipped,
    "epoch_credited_on_restart": epoch_credited_on_restart,
    "refund_in_contact": refund_in_contact,
    "model_rendered_outside_tank": model_rendered_outside_tank,
    "two_sided_damping_credit": two_sided_damping_credit,
    "object_work_sign_flipped": object_work_sign_flipped,
    "object_work_not_charged": object_work_not_charged,
    "reservation_ignored": reservation_ignored,
}


# ------------------------------------------------------------------------------ the checks
TOL_J = 1e-9


def _params(**kw: Any) -> ControlParams:
    return replace(control_params(ControllerConfig(kind="two-layer")), **kw)


def _rig_failure(positions: list[float], force_n: float, keep_reserve: bool) -> str:
    """Master side alone, fed commands that carry no energy: the work done on the operator
    must stay within its initial tank + the work taken from the operator (and, with
    ``keep_reserve``, leave the tank's reserve ``H_min`` untouched)."""
    p = _params(initial_j=0.05)
    tr = run_master_rig(CONTROLLERS["two-layer"], p, positions, force_n)
    floor = p.min_j if keep_reserve else 0.0
    worst = min(tr.margin_j(p.initial_j))
    if worst < floor - TOL_J:
        return (f"operator port: margin {worst:.4g} J < {floor:.4g} J "
                f"(delivered {tr.delivered_j[-1]:.4g} J, taken {tr.taken_j[-1]:.4g} J)")
    return ""


#: the trigger at rest at 25 mm for 0.1 s, opened steadily to 0 over 1 s, at rest 0.1 s
STEADY_RELEASE = ([0.025] * 100 + [0.025 * (1.0 - k / 1000) for k in range(1001)]
                  + [0.0] * 100)
#: the trigger shaken by 0.9 mm every sample (0.9 m/s, within the 1 m/s speed bound)
ZIGZAG = [0.0125 + (0.0009 if k % 2 else 0.0) for k in range(1500)]


def master_passive_steady(hand_port: str = "object") -> str:
    """The device pushes (5 N) while the operator opens the trigger steadily."""
    return _rig_failure(STEADY_RELEASE, 5.0, keep_reserve=False)


def master_keeps_reserve_steady(hand_port: str = "object") -> str:
    """As above; for steady motion Franken's limiter (which predicts the next sample's
    energy from the last velocity) stops the delivery at ``H_min``, so the operator gets at
    most ``initial - H_min`` + what it put in."""
    return _rig_failure(STEADY_RELEASE, 5.0, keep_reserve=True)


#: the trigger held deep in contact (20 mm) while a contact model arrives, then opened over 1 s
DEEP_RELEASE = [0.020] * 300 + [0.020 * (1.0 - k / 1000) for k in range(1001)] + [0.0] * 100
#: a stiff block: contact at 0.4 rad of set-point (3.3 mm of trigger), 40 N per rad
BLOCK_MODEL = (0.4, 40.0) * 3


def master_passive_rendered(hand_port: str = "object") -> str:
    """A contact model arrives while the operator is deep in it (its spring would hold ~0.13
    J, the tank 0.05 J), then the operator opens: what the rendered spring gives back must
    stay within the tank and what the operator put in."""
    p = _params(initial_j=0.05)
    tr = run_master_rig(CONTROLLERS["two-layer"], p, DEEP_RELEASE, 0.0, model=BLOCK_MODEL)
    worst = min(tr.margin_j(p.initial_j))
    if worst < -TOL_J:
        return (f"operator port: margin {worst:.4g} J (delivered {tr.delivered_j[-1]:.4g} J, "
                f"taken {tr.taken_j[-1]:.4g} J)")
    if max(tr.force_n) < 1.0:
        return "the model was never rendered"
    return ""


def master_passive_zigzag(hand_port: str = "object") -> str:
    """The device pushes (8 N) while the trigger reverses every sample: the last velocity
    predicts nothing, only the hard guard keeps the tank from being overdrawn."""
    return _rig_failure(ZIGZAG, 8.0, keep_reserve=False)


#: the operator closes slowly (full at 3 s) and holds; the fingers meet the wall at 0.3 rad
SQUEEZE = Scenario(seed=1, steps=4000, wall_rad=(0.3, 0.3, 0.3), hand_every=25,
                   ref_period_s=6.0, op_stiffness=1000.0)


def loop_passive_squeeze(hand_port: str = "object") -> str:
    """Closed-loop harness, 0.1 J tanks: energy delivered to the operator and to the wall <=
    initial tanks + energy taken from them, at every sample (harness physics)."""
    p = _params(initial_j=0.1, reserve_j=0.02, hand_port=hand_port)
    suite = CONTROLLERS["two-layer"]
    return audit_failure(run_loop(suite, p, SQUEEZE), initial_tank_j(suite, p))


#: lockstep: 0.1 J tanks, no reserve, half the surplus sent each sample (so energy flows)
LOCKSTEP_OVERRIDES = ("controller.tank.initial_j=0.1", "controller.tank.reserve_j=0.0",
                      "controller.tank.transfer_fraction=0.5",
                      "controller.tank.controller_fraction=0.5")
RESTART_AT_S = 1.5


def lockstep_passive_with_restart(hand_port: str = "object") -> str:
    """Lockstep run of the three services with the simulated operator (repeated grasps) and
    hand, the controller restarted at 1.5 s: the physical audit (``sim.operator`` /
    ``sim.audit``) must show delivered <= initial tanks + taken at every sample."""
    # the delayed-force path: with model-mediated rendering the master spends almost none of
    # what it is sent within the run (it keeps the rendered spring's energy), so a double
    # credit stays in the tanks (margin 0.2 -> 0.07 J, measured) instead of reaching a port
    cfg = load_config(None, [*LOCKSTEP_OVERRIDES, f"controller.ports.hand_port={hand_port}",
                             "controller.contact_model.enabled=false"])

    def hook(t_s: float, ctx: LockstepContext) -> None:
        if t_s >= RESTART_AT_S and ctx.controller_restarts == 0:
            ctx.restart_controller()

    r = run_lockstep(cfg, 5.0, seed=1, hook=hook)
    assert r.has_audit
    worst = float(np.min(r.audit_margin_j))
    if worst < -TOL_J:
        return f"lockstep audit: margin {worst:.4g} J at t = {r.t_s[np.argmin(r.audit_margin_j)]} s"
    return ""


#: the operator closes and holds against an object that yields (a box pushed across a table):
#: every joule the fingers put in is gone, so only the tank can stop them pushing
PUSH = Scenario(seed=2, steps=6000, wall_rad=(0.3, 0.3, 0.3), hand_every=25, ref_period_s=8.0,
                op_stiffness=1000.0, wall_speed_rad_s=0.05)


def loop_passive_yielding(hand_port: str = "object") -> str:
    """Closed-loop harness, 0.1 J tanks, the yielding object: the audit of the harness
    physics at every sample.  The yielding-contact guard is off here: it would charge the
    push at the servo's torque (far above the work really done) and so hide a ledger that
    gives away energy; with it off only the tank's books stand between the push and the
    bound (the guard's own mutants are in test_assumptions.py)."""
    p = _params(initial_j=0.1, reserve_j=0.02, hand_port=hand_port)
    p = replace(p, tactile=replace(p.tactile, yield_stiffness_ratio=0.0))
    suite = CONTROLLERS["two-layer"]
    return audit_failure(run_loop(suite, p, PUSH), initial_tank_j(suite, p))


#: repeated grasps into the wall with the hand at 40 Hz: opening and closing every second
CYCLES = Scenario(seed=3, steps=8000, hand_every=25, ref_period_s=1.0, ref_fraction=1.0,
                  wall_rad=(0.6, 0.6, 0.6))


def loop_passive_cycles(hand_port: str = "object") -> str:
    """Closed-loop harness, 0.1 J tanks, eight open-close cycles into the wall: the audit of
    the harness physics (work on the operator and on the wall) at every sample."""
    p = _params(initial_j=0.1, reserve_j=0.02, hand_port=hand_port)
    suite = CONTROLLERS["two-layer"]
    return audit_failure(run_loop(suite, p, CYCLES), initial_tank_j(suite, p))


def lockstep_passive_grasps(hand_port: str = "object") -> str:
    """Lockstep run, 8 s of the virtual operator's repeated grasps on the simulated hand,
    0.1 J tanks: the physical audit at every sample.  The force path is the delayed measured
    force (model-mediated rendering off): with the model on, what a starved hand lets the
    operator feel (``follow_held_back``) changes how the operator squeezes, and a protocol
    mutant that starves the hand then hides behind a gentler squeeze (margin +0.018 J at 8 s
    against -0.65 J with the model off)."""
    r = run_lockstep(load_config(None, [*LOCKSTEP_OVERRIDES,
                                        f"controller.ports.hand_port={hand_port}",
                                        "controller.contact_model.enabled=false"]), 8.0, seed=1)
    assert r.has_audit
    worst = float(np.min(r.audit_margin_j))
    if worst < -TOL_J:
        return f"lockstep audit: margin {worst:.4g} J at t = {r.t_s[np.argmin(r.audit_margin_j)]} s"
    return ""


CHECKS: dict[str, Callable[[str], str]] = {
    "master_passive_steady": master_passive_steady,
    "master_keeps_reserve_steady": master_keeps_reserve_steady,
    "master_passive_zigzag": master_passive_zigzag,
    "loop_passive_squeeze": loop_passive_squeeze,
    "lockstep_passive_with_restart": lockstep_passive_with_restart,
    "master_passive_rendered": master_passive_rendered,
    "loop_passive_cycles": loop_passive_cycles,
    "lockstep_passive_grasps": lockstep_passive_grasps,
    "loop_passive_yielding": loop_passive_yielding,
}

#: which check, with which hand layer (``controller.ports.hand_port``), catches which mutant
CAUGHT_BY: dict[str, tuple[str, str]] = {
    "port_work_sign_flipped": ("master_passive_steady", "object"),
    "dissipation_over_credited_x50": ("loop_passive_squeeze", "servo"),
    "franken_limiter_removed": ("master_keeps_reserve_steady", "object"),
    "guard_removed": ("master_passive_zigzag", "object"),
    # the mutant's receivers drop most states as "energy_decrease", so the controller's
    # hand-state watchdog trips; a blind hold engaged from the trip itself (not only once the
    # force has ramped below half, services.controller_service.BLIND_GAIN) starves the hand
    # of closing set-points and hides it here (margin +0.05 J against -0.086 J)
    "quanta_as_increments": ("lockstep_passive_grasps", "servo"),
    "store_below_zero": ("loop_passive_yielding", "object"),
    "setpoint_modulation_skipped": ("loop_passive_squeeze", "servo"),
    "epoch_credited_on_restart": ("lockstep_passive_with_restart", "servo"),
    "refund_in_contact": ("loop_passive_squeeze", "servo"),
    "model_rendered_outside_tank": ("master_passive_rendered", "object"),
    "two_sided_damping_credit": ("loop_passive_cycles", "servo"),
    "object_work_sign_flipped": ("loop_passive_squeeze", "object"),
    "object_work_not_charged": ("loop_passive_yielding", "object"),
    "reservation_ignored": ("loop_passive_squeeze", "object"),
}
USED = sorted(set(CAUGHT_BY.values()))


def test_every_mutant_has_a_check() -> None:
    assert set(CAUGHT_BY) == set(MUTANTS)
    assert {check for check, _ in CAUGHT_BY.values()} == set(CHECKS)


@pytest.mark.parametrize(("check", "hand_port"), USED)
def test_check_passes_unpatched(check: str, hand_port: str) -> None:
    fail = CHECKS[check](hand_port)
    assert not fail, fail


@pytest.mark.parametrize("mutant", sorted(MUTANTS))
def test_mutant_is_caught(mutant: str, monkeypatch: pytest.MonkeyPatch) -> None:
    MUTANTS[mutant](monkeypatch)
    check, hand_port = CAUGHT_BY[mutant]
    fail = CHECKS[check](hand_port)
    assert fail, f"{mutant} passed {CAUGHT_BY[mutant]}"
