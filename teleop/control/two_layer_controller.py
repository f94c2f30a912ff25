"""``two-layer``, controller: credits the increases of both incoming totals to its store,
forwards ``gamma * store`` split ``s : 1 - s`` to hand and master as running totals, and runs
the transparency layer with the delay-aware force gain of :mod:`teleop.control.delay_adapt`
and the unseen-touch cap of :mod:`teleop.control.touch_cap`.  The suite:
:mod:`teleop.control.two_layer`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from teleop.control.delay_adapt import DelayAdaptState, step_delay_adapt
from teleop.control.energy_channel import EnergyLedger, TotalReceiver, receive_total
from teleop.control.energy_tank import (
    cap_tank,
)
from teleop.control.interface import ControllerOutput, ControlParams
from teleop.control.memo import last_result
from teleop.control.touch_cap import unseen_touch_cap
from teleop.control.transparency_layer import (
    TransparencyState,
    grip_to_setpoints,
    transparency_force,
)
from teleop.frozen import fast_init
from teleop.messages import (
    NO_MODEL,
    ForceCommand,
    HandCommand,
    HandMode,
    HandState,
    Header,
    MasterState,
)

Triple = tuple[float, float, float]


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
    # (the received total is added as (received + rho inc_m) + inc_h, so not through book())
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
