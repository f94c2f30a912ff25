"""``two-layer``, master side (owns the operator's port; Franken et al. 2011): exact port energy
``w = -F(k-1) (q(k) - q(k-1))``, tank update ``H <- H - w + received``, upper limit, a quantum
``beta max(H - H_res, 0)`` sent as a monotone running total, then the desired force is limited
(Franken's limiter against ``H - H_min``, hard guard against ``H``), plus the tank level
controller's damping; the received contact model rendered locally
(:mod:`teleop.control.model_render`).  The suite: :mod:`teleop.control.two_layer`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from teleop.control.energy_channel import EnergyLedger, TotalReceiver, book, receive_total
from teleop.control.energy_tank import (
    cap_tank,
    franken_limit,
    guard_force,
    port_work_j,
    quantum_j,
    split_work,
    tlc_damping,
)
from teleop.control.interface import ControlParams, MasterOutput
from teleop.control.model_render import (
    RenderState,
    damping_n_s_per_m,
    model_energy_j,
    model_force_n,
    step_render,
)
from teleop.control.transparency_layer import (
    clip,
)
from teleop.frozen import fast_init
from teleop.messages import (
    NO_MODEL,
    ForceCommand,
)

Triple = tuple[float, float, float]


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
    led = book(led, tank, port_in_j=took, port_out_j=gave, sent_j=send, received_j=inc,
               dissipated_j=diss)
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
    r = step_render(r, p, model, q, tank_j - p.min_j, cm.force_rate_n_per_s, dt_s, cut,
                    cm.force_drop_rate_n_per_s)
    f = model_force_n(r, p, q)
    b = damping_n_s_per_m(r, p, cm.damping_periods, dt_s) if f > 0.0 else 0.0
    return r, f, b * v, model_energy_j(r, p, q)
