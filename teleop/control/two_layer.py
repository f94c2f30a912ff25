"""``two-layer``: Franken et al. (2011) transparency layer + passivity layer with energy tanks.

Master side (owns the operator's port): exact port energy ``w = -F(k-1) (q(k) - q(k-1))``,
tank update ``H <- H - w + received``, upper limit, a quantum ``beta max(H - H_res, 0)`` sent
as a monotone running total, then the desired force is limited (Franken's limiter against
``H - H_min``, hard guard against ``H``), plus the tank level controller's damping.
Controller: credits the increases of both incoming totals to its store, forwards
``gamma * store`` split ``s : 1 - s`` to hand and master as running totals, and runs the
transparency layer with the delay-aware force gain of :mod:`teleop.control.delay_adapt`
(round trip measured from the echoed timestamps; full gain at small delays).  Hand side
(``hand_port = "object"``, the default): its tank pays for the work the pads do on the object
(:mod:`teleop.control.object_port`) and the set-point may only go where what the finger could
still push into the object fits in the tank (:func:`~teleop.control.passivity_layer.
reserve_project`); ``hand_port = "servo"``: passive set-position modulation against the servo
spring's energy (:mod:`teleop.control.passivity_layer`).

See :mod:`teleop.control.energy_tank` and ``docs/controllers.md`` for the equations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from teleop.control.contact_model import FingerModel, model_wire, step_models
from teleop.control.delay_adapt import DelayAdaptState, step_delay_adapt
from teleop.control.energy_channel import EnergyLedger, TotalReceiver, receive_total
from teleop.control.energy_tank import (
    cap_tank,
    franken_limit,
    guard_force,
    port_work_j,
    quantum_j,
    split_work,
    tlc_damping,
)
from teleop.control.gain_check import UNCHECKED, GainTrack, check_gains
from teleop.control.interface import ControllerOutput, ControlParams, HandOutput, MasterOutput
from teleop.control.memo import last_result
from teleop.control.model_render import (
    RenderState,
    damping_n_s_per_m,
    model_energy_j,
    model_force_n,
    step_render,
)
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
from teleop.control.stall_guard import FREE, StallTrack, step_stall
from teleop.control.touch_cap import NO_TOUCH, hand_touch_cap, touch_since, unseen_touch_cap
from teleop.control.transparency_layer import (
    TransparencyState,
    clip,
    grip_to_setpoints,
    max_pressures,
    transparency_force,
)
from teleop.control.yield_guard import (
    NO_CONTACT,
    YieldTrack,
    pad_advance_m,
    step_yield,
    yield_charge_j,
)
from teleop.frozen import fast_init
from teleop.messages import (
    NO_MODEL,
    FingerState,
    ForceCommand,
    HandCommand,
    HandMode,
    HandState,
    Header,
    MasterState,
)

Triple = tuple[float, float, float]


# ----------------------------------------------------------------------------- master side
@fast_init
@dataclass(frozen=True, slots=True)
class MasterPortState:
    """Master side: last position and held force, incoming total, accounts."""

    ledger: EnergyLedger
    q_prev_m: float | None = None
    force_prev_n: float = 0.0
    rx: TotalReceiver = field(default_factory=TotalReceiver)
    render: RenderState = field(default_factory=RenderState)


def init_master(p: ControlParams) -> MasterPortState:
    """A full tank (``initial_j``), no force held."""
    return MasterPortState(ledger=EnergyLedger(initial_j=p.initial_j, tank_j=p.initial_j))


def measure_master(s: MasterPortState, grip_position_m: float,
                   dt_s: float) -> tuple[float, float, float]:
    """(q, dq, v) of this sample; a non-finite reading counts as no motion."""
    q_prev = s.q_prev_m
    q = grip_position_m if math.isfinite(grip_position_m) else (q_prev or 0.0)
    dq = 0.0 if q_prev is None else q - q_prev
    v = dq / dt_s if dt_s > 0 else 0.0
    return q, dq, v


def step_master(s: MasterPortState, p: ControlParams, grip_position_m: float,
                command: ForceCommand | None, dt_s: float) -> tuple[MasterPortState,
                                                                    MasterOutput]:
    """One master-side sample of the passivity layer (see module docstring)."""
    led = s.ledger
    q, dq, v = measure_master(s, grip_position_m, dt_s)
    w = port_work_j(s.force_prev_n, dq)
    took, gave = split_work(w)
    tank = led.tank_j - w
    rx, inc = receive_total(s.rx, command.header.energy_total_j if command else None)
    tank, diss = cap_tank(tank + inc, p.max_j)
    render, f_model, f_damp, hold = render_model(s.render, p, command, q, v, tank, dt_s)
    send = quantum_j(tank - hold, p.reserve_j, p.transfer_fraction)
    tank -= send
    f_des = clip(command.force_n, p.force_max_n) if command is not None else 0.0
    if render.phase > 0.0 or f_model > 0.0:  # the delayed force fades as the model comes in
        f_des = clip(max(f_model + f_damp, f_des * (1.0 - render.phase)), p.force_max_n)
    f_t = franken_limit(f_des, v, tank - p.min_j, dt_s)
    d = tlc_damping(tank, p.desired_j, p.tlc_gain, p.tlc_damping_max, p.trigger_mass_kg, dt_s)
    f_want = clip(f_t + d * v, p.force_max_n)
    f = guard_force(f_want, tank, v, p.trigger_max_speed_m_s, dt_s)
    led = EnergyLedger(initial_j=led.initial_j, tank_j=tank, port_in_j=led.port_in_j + took,
                       port_out_j=led.port_out_j + gave, sent_j=led.sent_j + send,
                       received_j=led.received_j + inc, dissipated_j=led.dissipated_j + diss)
    out = MasterOutput(force_n=f, grip_position_m=q, grip_velocity_m_s=v,
                       energy_total_j=led.sent_j, ledger=led, force_desired_n=f_des,
                       limited=(f_t != f_des) or (f != f_want), tlc_damping_n_s_per_m=d,
                       model_force_n=f_model, model_phase=render.phase)
    return MasterPortState(ledger=led, q_prev_m=q, force_prev_n=f, rx=rx, render=render), out


def render_model(r: RenderState, p: ControlParams, command: ForceCommand | None, q: float,
                 v: float, tank_j: float, dt_s: float) -> tuple[RenderState, float, float, float]:
    """Model-mediated rendering (:mod:`teleop.control.model_render`): the new rendered model,
    its spring force and damping force at ``q``, and the stored energy the tank must keep."""
    cm = p.contact_model
    if cm is None:
        return r, 0.0, 0.0, 0.0
    model = command.model if command is not None else NO_MODEL
    cut = command is None or command.force_n == 0.0  # a watchdog zeroes the whole command
    r = step_render(r, p, model, q, tank_j - p.min_j, cm.force_rate_n_per_s, dt_s, cut)
    f = model_force_n(r, p, q)
    b = damping_n_s_per_m(r, p, cm.damping_periods, dt_s) if f > 0.0 else 0.0
    return r, f, b * v, model_energy_j(r, p, q)


# ------------------------------------------------------------------------------ controller
@fast_init
@dataclass(frozen=True, slots=True)
class ControllerStoreState:
    """Controller: incoming totals, energy store, sent totals per link, force filter."""

    ledger: EnergyLedger = field(default_factory=EnergyLedger)
    rx_master: TotalReceiver = field(default_factory=TotalReceiver)
    rx_hand: TotalReceiver = field(default_factory=TotalReceiver)
    sent_to_master_j: float = 0.0
    sent_to_hand_j: float = 0.0
    transparency: TransparencyState = field(default_factory=TransparencyState)
    seq: int = 0
    adapt: DelayAdaptState = field(default_factory=DelayAdaptState)
    #: per finger: ``t_s`` of the first command that carried this touch's contact model to the
    #: master (nan: no model), for :func:`unseen_touch_cap`
    model_since: Triple = (math.nan, math.nan, math.nan)
    #: per finger: master time the master got that touch's model (nan: not yet)
    model_felt: Triple = (math.nan, math.nan, math.nan)


def init_controller(p: ControlParams) -> ControllerStoreState:
    """An empty store: the controller never starts with energy of its own."""
    return ControllerStoreState()


def transparency_commands(s: ControllerStoreState, p: ControlParams,
                          master: MasterState | None, hand: HandState | None,
                          dt_s: float, gain: float = 1.0
                          ) -> tuple[TransparencyState, Triple, float, Triple, float]:
    """(filter state, set-points, display force, max pressures, unfiltered force);
    ``gain``: the delay-aware force-feedback gain (:mod:`teleop.control.delay_adapt`)."""
    if master is not None:
        sp = grip_to_setpoints(master.grip_position_m, p)
    else:
        sp = (p.open_angle_rad,) * 3
    ts, force, mp, raw = transparency_force(s.transparency, p,
                                            hand.fingers if hand is not None else None, dt_s,
                                            gain)
    return ts, sp, force, mp, raw


@last_result
def forward_model(p: ControlParams, hand: HandState | None) -> tuple[float, ...]:
    """The hand's contact models as the master renders them: per enabled finger ``(contact_rad,
    k)``, ``k`` in N of trigger force per rad of set-point (pressure stiffness times
    ``force_per_pressure_n``); no model when rendering is off."""
    if p.contact_model is None or hand is None:
        return NO_MODEL
    out: list[float] = []
    for i in range(3):
        c, k = hand.contact_model[2 * i], hand.contact_model[2 * i + 1]
        ok = p.finger_enable[i] and k > 0.0 and math.isfinite(c) and math.isfinite(k)
        out += [c, k * p.force_per_pressure_n] if ok else [0.0, 0.0]
    return tuple(out)


def make_commands(p: ControlParams, seq: int, t_s: float, force_n: float, to_master_j: float,
                  setpoints: Triple, to_hand_j: float, model: tuple[float, ...] = NO_MODEL,
                  hand: HandState | None = None) -> tuple[ForceCommand, HandCommand]:
    """The two outgoing messages with their running energy totals; ``hand``: the hand state
    the commands were computed from (its time is echoed to the hand)."""
    fc = ForceCommand(header=Header(seq=seq, t_s=t_s, energy_total_j=to_master_j),
                      force_n=force_n, model=model)
    hc = HandCommand(header=Header(seq=seq, t_s=t_s, energy_total_j=to_hand_j),
                     finger_setpoint_rad=setpoints, preshape_rad=p.preshape_rad,
                     mode=HandMode.POSITION,
                     hand_echo_t_s=hand.header.t_s if hand is not None else -1.0)
    return fc, hc


def step_controller(s: ControllerStoreState, p: ControlParams, master: MasterState | None,
                    hand: HandState | None, t_s: float,
                    dt_s: float) -> tuple[ControllerStoreState, ControllerOutput]:
    """Credit incoming quanta, forward a share of the store, run the transparency layer."""
    led = s.ledger
    rx_m, inc_m = receive_total(s.rx_master, master.header.energy_total_j if master else None)
    rx_h, inc_h = receive_total(s.rx_hand, hand.header.energy_total_j if hand else None)
    # the store holds hand-side joules: master quanta are scaled up by rho on the way in and
    # down on the way out (rho = 1: plain conservation)
    rho = p.energy_scale
    store, diss = cap_tank(led.tank_j + rho * inc_m + inc_h, p.max_j)
    out = p.controller_fraction * max(store, 0.0)
    to_h = p.controller_split * out
    to_m = (out - to_h) / rho
    store -= out
    led = EnergyLedger(initial_j=led.initial_j, tank_j=store, port_in_j=led.port_in_j,
                       port_out_j=led.port_out_j, sent_j=led.sent_j + out,
                       received_j=led.received_j + rho * inc_m + inc_h,
                       dissipated_j=led.dissipated_j + diss)
    adapt = step_delay_adapt(s.adapt, p.delay_adapt, master, hand, t_s, dt_s)
    ts, sp, force, mp, raw = transparency_commands(s, p, master, hand, dt_s, adapt.gain)
    seq = s.seq + 1
    sent_m, sent_h = s.sent_to_master_j + to_m, s.sent_to_hand_j + to_h
    model = forward_model(p, hand)
    since, felt, sp = unseen_touch_cap(s.model_since, p, model, master, sp, t_s, s.model_felt)
    fc, hc = make_commands(p, seq, t_s, force, sent_m, sp, sent_h, model, hand)
    ns = ControllerStoreState(ledger=led, rx_master=rx_m, rx_hand=rx_h, sent_to_master_j=sent_m,
                              sent_to_hand_j=sent_h, transparency=ts, seq=seq, adapt=adapt,
                              model_since=since, model_felt=felt)
    return ns, ControllerOutput(force_command=fc, hand_command=hc, ledger=led,
                                max_pressure=mp, force_desired_n=raw, force_gain=adapt.gain,
                                round_trip_s=adapt.round_trip_s)


# ------------------------------------------------------------------------------- hand side
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


def guard_fingers(p: ControlParams, s: HandPortState, pads: tuple[PadTrack, ...],
                  x: Triple) -> tuple[YieldTrack, ...]:
    """The yielding-contact guard's step for the three fingers: each one's total pad force
    and the pads' force-weighted advance driven by the proximal joint over the sample."""
    before = s.pads or pads
    t = p.tactile
    out = []
    for g, a, b, x_i in zip(s.yields, before, pads, x, strict=False):
        adv = pad_advance_m((b.prox_force_n, b.dist_force_n), (b.prox_x_m, b.dist_x_m),
                            b.proximal_rad - a.proximal_rad, b.distal_rad,
                            t.proximal_length_m)
        out.append(step_yield(g, b.prox_force_n + b.dist_force_n, adv, x_i,
                              t.yield_window_m, t.yield_stiffness_ratio))
    return tuple(out)


def stall_fingers(p: ControlParams, s: HandPortState, pads: tuple[PadTrack, ...],
                  fingers: tuple[FingerState, ...], x: Triple) -> tuple[StallTrack, ...]:
    """The unseen-contact guard's step for the three fingers
    (:mod:`teleop.control.stall_guard`): motor angle, proximal encoder, cells' pad force."""
    t = p.tactile
    return tuple(step_stall(g, x_i, f.proximal_rad, b.prox_force_n + b.dist_force_n,
                            t.stall_window_rad, t.stall_ratio, t.free_curl_rad)
                 for g, b, f, x_i in zip(s.stalls, pads, fingers, x, strict=False))


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
    gains, works, recharge = check_gains(p.tactile, s.gains, pads, fingers[:3], works, dt_s)
    yields = guard_fingers(p, s, pads, x)
    stalls = stall_fingers(p, s, pads, fingers[:3], x)
    blind = tuple(g.yielding or h.stalled for g, h in zip(yields, stalls, strict=False))
    trusted = [w for w, b in zip(works, blind, strict=False) if not b]
    net = s.object_net_j + sum(o for o, _ in trusted) - sum(i for _, i in trusted)
    paid = margin_charge_j(p.tactile, s.object_net_j)
    charge = margin_charge_j(p.tactile, net) - paid
    # a yielding finger's cells are not trusted, a stalled one's see nothing: its inward
    # motion is charged at the servo's torque (teleop.control.yield_guard, .stall_guard)
    crush = (yield_charge_j(x, s.x_prev, blind, p.servo_torque_max_nm)
             if s.x_prev is not None else 0.0)
    # one sample cannot deliver more than the fingers held at its start (servo potential,
    # tendon) plus their kinetic energy: a slip off the object, where the sampled estimate
    # sees a large force over a long move, is charged no more than that
    cap = s.held_j + p.finger_kinetic_j * len(fingers[:3])
    crush = min(crush, cap)
    if charge > cap - crush:
        charge = cap - crush
        net = margin_net_j(p.tactile, paid + charge)
    if recharge > 0.0:  # past samples' work at the raised scale: outside the one-sample cap
        before, net = margin_charge_j(p.tactile, net), net + recharge
        charge += margin_charge_j(p.tactile, net) - before
    charge += crush
    out_j, in_j = max(charge, 0.0), max(-charge, 0.0)
    rx, inc = receive_total(s.rx, command.header.energy_total_j if command else None)
    tank, diss = cap_tank(led.tank_j - charge + inc, p.max_j)
    k, tmax, kt = p.servo_stiffness_nm_per_rad, p.servo_torque_max_nm, \
        p.tendon_stiffness_nm_per_rad
    want = slew(desired_setpoints(command, y_prev), y_prev, p.servo_max_speed_rad_s * dt_s, x)
    y, limited = reserve_project(want, x, tank - p.min_j, k, tmax, kt)
    held = hand_reservation_j(y, x, k, tmax, kt)
    send = quantum_j(tank - max(hand_hold_j(p), held), p.reserve_j, p.transfer_fraction)
    tank -= send
    led = EnergyLedger(initial_j=led.initial_j, tank_j=tank,
                       port_in_j=led.port_in_j + in_j, port_out_j=led.port_out_j + out_j,
                       sent_j=led.sent_j + send, received_j=led.received_j + inc,
                       dissipated_j=led.dissipated_j + diss)
    pre = command.preshape_rad if command is not None else p.preshape_rad
    out = HandOutput(setpoint_rad=y, preshape_rad=pre, energy_total_j=led.sent_j, ledger=led,
                     setpoint_desired_rad=want, limited=limited, spring_energy_j=held,
                     yielding=sum(1 for g in yields if g.yielding),
                     unseen=sum(1 for h in stalls if h.stalled),
                     cells_low=sum(1 for g in gains if g.low))
    return HandPortState(ledger=led, x_prev=x, setpoint_prev=y, rx=rx, pads=pads,
                         object_net_j=net, held_j=held, models=s.models, yields=yields,
                         stalls=stalls, gains=gains), out


def step_hand(s: HandPortState, p: ControlParams, fingers: tuple[FingerState, ...],
              command: HandCommand | None, dt_s: float,
              t_s: float = math.nan) -> tuple[HandPortState, HandOutput]:
    """One hand-side sample at hand time ``t_s``: the hand's touch cap
    (:func:`~teleop.control.touch_cap.hand_touch_cap`; off without a finite ``t_s``), the
    passivity layer (:func:`step_hand_object`, or :func:`step_hand_servo` for ``hand_port =
    "servo"``), then the contact models (:mod:`teleop.control.contact_model`) on the set-point
    that was in force over the sample, the measured motor angles and peak pressures."""
    step = step_hand_object if p.hand_port == "object" else step_hand_servo
    if p.contact_model is not None:
        command = hand_touch_cap(p, s.models, s.touch_since, command,
                                 max_pressures(fingers, p), measure_hand(s, fingers))
    ns, out = step(s, p, fingers, command, dt_s)
    if p.contact_model is None or s.setpoint_prev is None:
        return ns, out
    assert ns.x_prev is not None  # both layers keep this sample's measured motor angles
    models = step_models(s.models, p.contact_model, s.setpoint_prev, ns.x_prev,
                         max_pressures(fingers, p), dt_s)
    since = touch_since(s.touch_since, models, t_s)
    return (replace(ns, models=models, touch_since=since),
            replace(out, contact_model=model_wire(models),
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
    led = EnergyLedger(initial_j=led.initial_j, tank_j=tank,
                       port_in_j=led.port_in_j + max(-e, 0.0),
                       port_out_j=led.port_out_j + max(e, 0.0), sent_j=led.sent_j + send,
                       received_j=led.received_j + inc, dissipated_j=led.dissipated_j + diss)
    pre = command.preshape_rad if command is not None else p.preshape_rad
    out = HandOutput(setpoint_rad=y, preshape_rad=pre, energy_total_j=led.sent_j, ledger=led,
                     setpoint_desired_rad=want, limited=limited,
                     spring_energy_j=spring_energy_j(y, x, p.servo_stiffness_nm_per_rad,
                                                     p.servo_torque_max_nm))
    return HandPortState(ledger=led, x_prev=x, setpoint_prev=y, rx=rx,
                         contact_prev=contact, models=s.models), out
