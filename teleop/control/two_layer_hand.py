"""``two-layer``, hand side.  ``hand_port = "object"`` (the default): the tank pays for the
work the pads do on the object (:mod:`teleop.control.object_port`) and the set-point may only
go where what the finger could still push into the object fits in the tank
(:func:`~teleop.control.passivity_layer.reserve_project`); ``hand_port = "servo"``: passive
set-position modulation against the servo spring's energy
(:mod:`teleop.control.passivity_layer`).  The hand's touch cap, the guards (yield, unseen
contact, gain cross-check) and the contact models run here.  The suite:
:mod:`teleop.control.two_layer`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from teleop.control.contact_model import FingerModel, model_wire, step_models
from teleop.control.energy_channel import EnergyLedger, TotalReceiver, book, receive_total
from teleop.control.energy_tank import (
    cap_tank,
    quantum_j,
)
from teleop.control.gain_check import UNCHECKED, GainTrack, check_gains, set_charge_j
from teleop.control.interface import ControlParams, HandOutput
from teleop.control.object_port import PadTrack, margin_charge_j, margin_net_j, track_fingers
from teleop.control.passivity_layer import (
    dissipation_lower_bound_j,
    hand_reservation_j,
    pspm_project,
    reservation_j,
    reserve_project,
    servo_potential_j,
    spring_energy_j,
)
from teleop.control.stall_guard import FREE, StallTrack, stall_recharge_j, step_stall
from teleop.control.touch_cap import NO_TOUCH, hand_touch_cap, touch_since
from teleop.control.transparency_layer import (
    max_pressures,
)
from teleop.control.yield_guard import (
    NO_CONTACT,
    SET_FOUND,
    YieldTrack,
    flag_recharges_j,
    pad_advance_m,
    step_yield,
    yield_charges_j,
)
from teleop.frozen import fast_init
from teleop.messages import (
    FingerState,
    HandCommand,
    HandMode,
)

Triple = tuple[float, float, float]


@fast_init
@dataclass(frozen=True, slots=True)
class HandPortState:
    """Hand side: last measured motor angles and set-points, incoming total, accounts."""

    ledger: EnergyLedger
    x_prev: Triple | None = None
    setpoint_prev: Triple | None = None
    rx: TotalReceiver = field(default_factory=TotalReceiver)
    contact_prev: tuple[bool, bool, bool] = (True, True, True)
    pads: tuple[PadTrack, ...] | None = None
    object_net_j: float = 0.0  # estimated net work on the object so far (before the margin)
    held_j: float = 0.0  # what the fingers could push into the object after the last sample
    models: tuple[FingerModel, ...] | None = None  # contact model per finger (rendering on)
    yields: tuple[YieldTrack, ...] = (NO_CONTACT, NO_CONTACT, NO_CONTACT)  # yield guard
    stalls: tuple[StallTrack, ...] = (FREE, FREE, FREE)  # unseen-contact guard
    gains: tuple[GainTrack, ...] = (UNCHECKED, UNCHECKED, UNCHECKED)  # gain cross-check
    #: per finger: hand time its contact model became valid (nan: none), for the hand's
    #: touch cap (:func:`teleop.control.touch_cap.hand_touch_cap`)
    touch_since: Triple = NO_TOUCH
    #: the set-points the layer would apply if its tank never held them back
    #: (:func:`shadow_setpoints`; None before the first sample)
    shadow_rad: Triple | None = None
    #: per finger: what its contact has paid at the servo's worst case (yield flag re-charge
    #: and the flagged samples' motion), and what of it was credited back once the gain
    #: cross-check measured the cells in the contact (:func:`worst_case_credit_j`)
    worst_j: Triple = (0.0, 0.0, 0.0)
    credited_j: Triple = (0.0, 0.0, 0.0)


def init_hand(p: ControlParams) -> HandPortState:
    """A full tank; the first set-point is the measured position (no spring energy)."""
    return HandPortState(ledger=EnergyLedger(initial_j=p.initial_j, tank_j=p.initial_j))


def measure_hand(s: HandPortState, fingers: tuple[FingerState, ...]) -> Triple:
    """Joint-side motor angles of the three fingers (non-finite -> previous value)."""
    prev = s.x_prev or (0.0, 0.0, 0.0)
    vals = [f.motor_angle_rad for f in fingers[:3]]
    vals += [prev[i] for i in range(len(vals), 3)]
    return tuple(v if math.isfinite(v) else prev[i]  # type: ignore[return-value]
                 for i, v in enumerate(vals))


def sample_hand_port(s: HandPortState, p: ControlParams, fingers: tuple[FingerState, ...],
                     dt_s: float) -> tuple[Triple, Triple, float]:
    """One hand-port sample: measured angles ``x``, the previous set-point (``x`` at the first
    sample) and the energy the servo damping dissipated at least since the last sample."""
    x = measure_hand(s, fingers)
    y_prev = s.setpoint_prev if s.setpoint_prev is not None else x
    d_j = (dissipation_lower_bound_j(x, s.x_prev, p.servo_damping_nm_s_per_rad, dt_s)
           if s.x_prev is not None else 0.0)
    return x, y_prev, d_j


def desired_setpoints(command: HandCommand | None, hold: Triple) -> Triple:
    """The commanded set-points (position mode, finite) or ``hold``."""
    if command is None or command.mode != HandMode.POSITION:
        return hold
    sp = tuple(command.finger_setpoint_rad[:3])
    if len(sp) != 3 or not all(math.isfinite(v) for v in sp):
        return hold
    return sp  # type: ignore[return-value]


def slew(want: Triple, prev: Triple, max_step: float, x: Triple | None = None) -> Triple:
    """``want`` reached from ``prev`` by steps of at most ``max_step`` per finger; a set-point
    ahead of its motor (``x``) that is to come back drops to the motor at once (the servo
    spring's energy only falls on the way)."""
    if x is None:
        return tuple(b + min(max(a - b, -max_step), max_step)  # type: ignore[return-value]
                     for a, b in zip(want, prev, strict=True))
    return tuple(b + min(max(a - b, -max(max_step, b - m)), max_step)  # type: ignore[return-value]
                 for a, b, m in zip(want, prev, x, strict=True))


def shadow_setpoints(s: HandPortState, p: ControlParams, command: HandCommand | None,
                     x: Triple, dt_s: float) -> Triple:
    """The set-points the layer would apply if its tank never held them back: the command
    slewed from the previous shadow exactly as the layer slews its own (equal to the applied
    set-points, float for float, while the tank has never limited them)."""
    prev = (s.shadow_rad if s.shadow_rad is not None
            else s.setpoint_prev if s.setpoint_prev is not None else x)
    step = p.servo_max_speed_rad_s * dt_s
    return slew(desired_setpoints(command, prev), prev, step,
                x if p.hand_port == "object" else None)


def finger_contacts(fingers: tuple[FingerState, ...]) -> tuple[bool, bool, bool]:
    """Per finger: does any tactile cell report contact (a missing finger counts as yes)."""
    c = [any(f.contact) for f in fingers[:3]]
    return tuple(c + [True] * (3 - len(c)))  # type: ignore[return-value]


def free_motion_refund_j(s: HandPortState, p: ControlParams, x: Triple, y_prev: Triple,
                         free: tuple[bool, bool, bool]) -> float:
    """Signed change of the servo-spring energy that finger motion caused over the last
    sample (set-point held), summed over the fingers that touched nothing at either end of
    it: the servo's work on a finger in free motion stays inside the hand (its springs,
    friction, rotor), so it goes back to the tank; energy the finger's springs push back
    into the servo spring is charged the same way (``H + sum P`` stays constant)."""
    if s.x_prev is None:
        return 0.0
    k, tmax = p.servo_stiffness_nm_per_rad, p.servo_torque_max_nm
    return sum(servo_potential_j(y_prev[i] - s.x_prev[i], k, tmax)
               - servo_potential_j(y_prev[i] - x[i], k, tmax)
               for i in range(3) if free[i])


def hand_hold_j(p: ControlParams) -> float:
    """What the hand's tank keeps before it sends energy on: the reservation that lets every
    enabled finger squeeze at the servo's full torque (``e = tau_max / K``)."""
    k, tmax = p.servo_stiffness_nm_per_rad, p.servo_torque_max_nm
    n = sum(1 for on in p.finger_enable[:3] if on)
    return n * reservation_j(tmax / k, k, tmax, p.tendon_stiffness_nm_per_rad)


def worst_case_credit_j(worst_j: Triple, credited_j: Triple, gains: tuple[GainTrack, ...]
                        ) -> tuple[Triple, float]:
    """What goes back to the tank of a flagged finger's worst-case charges once the gain
    cross-check has measured its cells in the contact: the contact needs no more than ``r``
    times the cells' estimated work into the object (``r`` the largest ratio of its resolved
    windows: ``1/g <= r``), so what it paid at the servo's worst case beyond that is
    credited.  The credit so far follows ``max(worst - r W, 0)`` as ``r`` and ``W`` grow (a
    fall is charged back).  Returns the credit so far per finger and this sample's change."""
    out, delta = [], 0.0
    for w, c, g in zip(worst_j, credited_j, gains, strict=False):
        target = max(w - g.contact_ratio * g.contact_into_j, 0.0) if g.contact_ratio > 0 else 0.0
        out.append(target)
        delta += target - c
    return tuple(out), delta  # type: ignore[return-value]


def credit_fingers(s: HandPortState, moved: Triple, flags: Triple,
                   gains: tuple[GainTrack, ...], crush_share: float
                   ) -> tuple[Triple, Triple, float]:
    """``yield_credit``'s bookkeeping for one sample: each finger's worst-case charges over
    its contact (``moved``, the flagged samples' motion at the servo's torque, ``crush_share``
    of it as the one-sample cap let through, and ``flags``, the flag's re-charge: the
    per-finger charges :func:`step_hand_object` made; a contact whose gain track has ended
    starts again at 0) and the credit (:func:`worst_case_credit_j`).  Returns ``(worst,
    credited, this sample's credit)``."""
    ended = [g.contact_into_j == 0.0 and g.contact_ratio == 0.0 for g in gains]
    worst = tuple(0.0 if e else w + m * crush_share + f
                  for w, m, f, e in zip(s.worst_j, moved, flags, ended, strict=False))
    credited0 = tuple(0.0 if e else c for c, e in zip(s.credited_j, ended, strict=False))
    credited, credit = worst_case_credit_j(worst, credited0, gains)  # type: ignore[arg-type]
    return worst, credited, credit  # type: ignore[return-value]


def guard_fingers(p: ControlParams, s: HandPortState, pads: tuple[PadTrack, ...],
                  x: Triple, works: tuple[tuple[float, float], ...] = ()
                  ) -> tuple[tuple[YieldTrack, ...], float]:
    """The yielding-contact guard's step for the three fingers: each one's total pad force
    and the pads' force-weighted advance driven by the proximal joint over the sample.
    Returns the tracks and what the sets found at the contacts' ends cost the fingers whose
    cells the gain cross-check measured in that contact (:func:`set_charge_j`, ``works``
    the cells' ``(into, back)`` over the sample, before any scale): those are charged that
    and not flagged; a set on a finger no window measured flags it (the servo's worst case,
    :func:`flag_recharge_j`)."""
    before = s.pads or pads
    t = p.tactile
    x_prev = s.x_prev or x
    out, set_j = [], 0.0
    for i, (g, a, b, x_i, w_i) in enumerate(zip(s.yields, before, pads, x, x_prev,
                                                  strict=False)):
        adv = pad_advance_m((b.prox_force_n, b.dist_force_n), (b.prox_x_m, b.dist_x_m),
                            b.proximal_rad - a.proximal_rad, b.distal_rad,
                            t.proximal_length_m)
        y = step_yield(g, b.prox_force_n + b.dist_force_n, adv, x_i, t.yield_window_m,
                       t.yield_stiffness_ratio, w_i, t.yield_set_check)
        if y is SET_FOUND and i < len(s.gains):
            into = works[i][0] if i < len(works) else 0.0
            measured = set_charge_j(s.gains[i], into, t.force_margin)
            if measured is not None:
                y, set_j = NO_CONTACT, set_j + measured
        out.append(y)
    return tuple(out), set_j


def stall_fingers(p: ControlParams, s: HandPortState, pads: tuple[PadTrack, ...],
                  fingers: tuple[FingerState, ...], x: Triple) -> tuple[StallTrack, ...]:
    """The unseen-contact guard's step for the three fingers
    (:mod:`teleop.control.stall_guard`): motor angle, proximal encoder, cells' pad force."""
    t = p.tactile
    x_prev = s.x_prev or x
    return tuple(step_stall(g, x_i, f.proximal_rad, b.prox_force_n + b.dist_force_n,
                            t.stall_window_rad, t.stall_ratio, t.free_curl_rad, w_i)
                 for g, b, f, x_i, w_i in zip(s.stalls, pads, fingers, x, x_prev,
                                              strict=False))


def step_hand_object(s: HandPortState, p: ControlParams, fingers: tuple[FingerState, ...],
                     command: HandCommand | None,
                     dt_s: float) -> tuple[HandPortState, HandOutput]:
    """One hand-side sample, environment-port accounting: the tank pays the (safe-side) work
    the pads did on the object since the last sample and is credited what the object gave
    back; the set-point may only go where the energy it could still push into the object
    (servo potential + tendon stretch, :func:`reservation_j`) fits in the tank."""
    led = s.ledger
    x = measure_hand(s, fingers)
    y_prev = s.setpoint_prev if s.setpoint_prev is not None else x
    pads, works = track_fingers(p.tactile, s.pads, fingers[:3])
    # cells found reading low against the servo's load: their work scaled up, the earlier
    # work re-charged (teleop.control.gain_check; nothing changes while none is)
    gains, scaled, recharge = check_gains(p.tactile, s.gains, pads, fingers[:3], works,
                                          dt_s)
    yields, set_j = guard_fingers(p, s, pads, x, works)
    works = scaled
    stalls = stall_fingers(p, s, pads, fingers[:3], x)
    blind = tuple(g.yielding or h.stalled for g, h in zip(yields, stalls, strict=False))
    trusted = [w for w, b in zip(works, blind, strict=False) if not b]
    net = s.object_net_j + sum(o for o, _ in trusted) - sum(i for _, i in trusted)
    paid = margin_charge_j(p.tactile, s.object_net_j)
    charge = margin_charge_j(p.tactile, net) - paid
    # a yielding finger's cells are not trusted, a stalled one's see nothing: its inward
    # motion is charged at the servo's torque (teleop.control.yield_guard, .stall_guard)
    tmax = p.servo_torque_max_nm
    moved: Triple = (yield_charges_j(x, s.x_prev, blind, tmax)  # type: ignore[assignment]
                     if s.x_prev is not None else (0.0, 0.0, 0.0))
    crush = sum(moved)
    # a finger just flagged: its advance before the flag, which the cells were trusted for
    # (yield) or saw nothing of (stall), at the servo's torque too (outside the one-sample
    # cap: past samples' work)
    # a set found when a measured finger's contact ended: the part of the contact's work
    # its measured gain leaves unpaid (outside the cap too)
    flags: Triple = flag_recharges_j(s.yields, yields, tmax)  # type: ignore[assignment]
    flagged = sum(flags) + stall_recharge_j(s.stalls, stalls, tmax) + set_j
    # one sample cannot deliver more than the fingers held at its start (servo potential,
    # tendon) plus their kinetic energy: a slip off the object, where the sampled estimate
    # sees a large force over a long move, is charged no more than that
    cap = s.held_j + p.finger_kinetic_j * len(fingers[:3])
    crush_all = crush
    crush = min(crush, cap)
    if charge > cap - crush:
        charge = cap - crush
        net = margin_net_j(p.tactile, paid + charge)
    if recharge > 0.0:  # past samples' work at the raised scale: outside the one-sample cap
        before, net = margin_charge_j(p.tactile, net), net + recharge
        charge += margin_charge_j(p.tactile, net) - before
    charge += crush + flagged
    # worst-case charges per finger this contact, credited back once its cells are measured
    # (``yield_credit``; off: nothing kept)
    worst, credited = s.worst_j, s.credited_j
    if p.tactile.yield_credit:
        share = crush / crush_all if crush_all > 0.0 else 0.0
        worst, credited, credit = credit_fingers(s, moved, flags, gains, share)
        charge -= credit
    out_j, in_j = max(charge, 0.0), max(-charge, 0.0)
    rx, inc = receive_total(s.rx, command.header.energy_total_j if command else None)
    tank, diss = cap_tank(led.tank_j - charge + inc, p.max_j)
    k, kt = p.servo_stiffness_nm_per_rad, p.tendon_stiffness_nm_per_rad
    want = slew(desired_setpoints(command, y_prev), y_prev, p.servo_max_speed_rad_s * dt_s, x)
    y, limited = reserve_project(want, x, tank - p.min_j, k, tmax, kt)
    held = hand_reservation_j(y, x, k, tmax, kt)
    send = quantum_j(tank - max(hand_hold_j(p), held), p.reserve_j, p.transfer_fraction)
    tank -= send
    led = book(led, tank, port_in_j=in_j, port_out_j=out_j, sent_j=send, received_j=inc,
               dissipated_j=diss)
    pre = command.preshape_rad if command is not None else p.preshape_rad
    out = HandOutput(setpoint_rad=y, preshape_rad=pre, energy_total_j=led.sent_j, ledger=led,
                     setpoint_desired_rad=want, limited=limited, spring_energy_j=held,
                     yielding=sum(1 for g in yields if g.yielding),
                     unseen=sum(1 for h in stalls if h.stalled),
                     cells_low=sum(1 for g in gains if g.low))
    return HandPortState(ledger=led, x_prev=x, setpoint_prev=y, rx=rx, pads=pads,
                         object_net_j=net, held_j=held, models=s.models, yields=yields,
                         stalls=stalls, gains=gains, worst_j=worst,
                         credited_j=credited), out


def step_hand(s: HandPortState, p: ControlParams, fingers: tuple[FingerState, ...],
              command: HandCommand | None, dt_s: float,
              t_s: float = math.nan) -> tuple[HandPortState, HandOutput]:
    """One hand-side sample at hand time ``t_s``: the hand's touch cap
    (:func:`~teleop.control.touch_cap.hand_touch_cap`; off without a finite ``t_s``), the
    passivity layer (:func:`step_hand_object`, or :func:`step_hand_servo` for ``hand_port =
    "servo"``), then the contact models (:mod:`teleop.control.contact_model`) on the set-point
    that was in force over the sample, the measured motor angles and peak pressures."""
    step = step_hand_object if p.hand_port == "object" else step_hand_servo
    if p.contact_model is None:
        return step(s, p, fingers, command, dt_s)
    peaks = max_pressures(fingers, p)  # for the cap and the models: computed once
    command = hand_touch_cap(p, s.models, s.touch_since, command, peaks,
                             measure_hand(s, fingers))
    ns, out = step(s, p, fingers, command, dt_s)
    if s.setpoint_prev is None:
        return ns, out
    assert ns.x_prev is not None  # both layers keep this sample's measured motor angles
    models = step_models(s.models, p.contact_model, s.setpoint_prev, ns.x_prev, peaks, dt_s)
    since = touch_since(s.touch_since, models, t_s)
    shadow, gap = None, ()
    if p.contact_model.follow_held_back:  # the model moved out by what the tank holds back
        shadow = shadow_setpoints(s, p, command, ns.x_prev, dt_s)
        gap = tuple(a - b for a, b in zip(shadow, out.setpoint_rad, strict=True))
    return (replace(ns, models=models, touch_since=since, shadow_rad=shadow),
            replace(out, contact_model=model_wire(models, gap),
                    model_fallbacks=sum(m.fallbacks for m in models)))


def step_hand_servo(s: HandPortState, p: ControlParams, fingers: tuple[FingerState, ...],
                    command: HandCommand | None,
                    dt_s: float) -> tuple[HandPortState, HandOutput]:
    """One hand-side sample of the servo-spring layer: dissipation credit, free-motion refund,
    quanta, set-position modulation."""
    led = s.ledger
    x, y_prev, d_all = sample_hand_port(s, p, fingers, dt_s)
    contact = finger_contacts(fingers)
    free = tuple(not (a or b) for a, b in zip(contact, s.contact_prev, strict=True))
    if p.free_motion_refund and any(free):
        # free fingers: the refund replaces the damping credit (never both)
        x_c = tuple(s.x_prev[i] if free[i] and s.x_prev is not None else x[i]
                    for i in range(3))
        d_j = (dissipation_lower_bound_j(x_c, s.x_prev, p.servo_damping_nm_s_per_rad, dt_s)
               if s.x_prev is not None else 0.0)
        d_j += free_motion_refund_j(s, p, x, y_prev, free)  # type: ignore[arg-type]
    else:
        d_j = d_all
    rx, inc = receive_total(s.rx, command.header.energy_total_j if command else None)
    tank, diss = cap_tank(led.tank_j + d_j + inc, p.max_j)
    send = quantum_j(tank, p.reserve_j, p.transfer_fraction)
    tank -= send
    want = slew(desired_setpoints(command, y_prev), y_prev, p.servo_max_speed_rad_s * dt_s)
    y, dp, limited = pspm_project(want, y_prev, x, tank - p.min_j,
                                  p.servo_stiffness_nm_per_rad, p.servo_torque_max_nm)
    tank -= dp
    e = dp - d_j
    led = book(led, tank, port_in_j=max(-e, 0.0), port_out_j=max(e, 0.0), sent_j=send,
               received_j=inc, dissipated_j=diss)
    pre = command.preshape_rad if command is not None else p.preshape_rad
    out = HandOutput(setpoint_rad=y, preshape_rad=pre, energy_total_j=led.sent_j, ledger=led,
                     setpoint_desired_rad=want, limited=limited,
                     spring_energy_j=spring_energy_j(y, x, p.servo_stiffness_nm_per_rad,
                                                     p.servo_torque_max_nm))
    return HandPortState(ledger=led, x_prev=x, setpoint_prev=y, rx=rx,
                         contact_prev=contact, models=s.models), out
