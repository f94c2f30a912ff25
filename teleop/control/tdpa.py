"""``tdpa``: two-port time-domain passivity (Ryu, Artigas and Preusche 2010).

Each side splits its port energy into cumulative ``E_in`` (taken from the port) and
``E_out`` (delivered) and sends ``E_in`` as a monotone running total (the receiver keeps
the maximum seen, so loss, duplication and reordering are tolerated).  The controller only
relays the two totals (master's ``E_in`` to the hand, hand's ``E_in`` to the master) and runs
the transparency layer.  Each side may deliver only what the other side has taken in plus an
initial budget ``E0`` (``tank.initial_j``):

* master: ``W_M = E0 + E_in,hand(delayed) - E_out,master >= 0``; the desired force is limited
  with Franken's limiter against ``W_M`` and the hard guard (so ``W_M`` can never go
  negative, which replaces Ryu's after-the-fact damping ``f' = f - W_M / (T v)``);
* hand: ``W_S = E0 + E_in,master(delayed) - E_out,hand >= 0``; the set-point is modulated
  (Lee and Huang's projection) so the net servo-spring energy injected this sample,
  ``dP - D``, never exceeds ``W_S`` (Ryu's velocity modification ``v' = v + W_S / (T f)``
  adapted to a position servo).

Summed: energy delivered at both ports <= 2 E0 + energy taken from both ports.  The budget is
capped at ``tank.max_j`` (the excess is dissipated): the observed energy cannot pile up.
"""

from __future__ import annotations

import math

from teleop.control.energy_channel import EnergyLedger, book, receive_total
from teleop.control.energy_tank import (
    cap_tank,
    franken_limit,
    guard_force,
    port_work_j,
    split_work,
)
from teleop.control.interface import ControllerOutput, ControlParams, HandOutput, MasterOutput
from teleop.control.passivity_layer import (
    pspm_project,
    spring_energy_j,
)
from teleop.control.transparency_layer import clip
from teleop.control.two_layer_controller import (
    ControllerStoreState,
    make_commands,
    transparency_commands,
)
from teleop.control.two_layer_hand import (
    HandPortState,
    desired_setpoints,
    sample_hand_port,
    slew,
)
from teleop.control.two_layer_master import (
    MasterPortState,
    measure_master,
)
from teleop.messages import FingerState, ForceCommand, HandCommand, HandState, MasterState


def init_master(p: ControlParams) -> MasterPortState:
    """Budget ``W_M = E0``; ``ledger.tank_j`` holds ``W_M``, ``sent_j`` is ``E_in``."""
    return MasterPortState(ledger=EnergyLedger(initial_j=p.initial_j, tank_j=p.initial_j))


def step_master(s: MasterPortState, p: ControlParams, grip_position_m: float,
                command: ForceCommand | None, dt_s: float) -> tuple[MasterPortState,
                                                                    MasterOutput]:
    """Passivity observer + controller at the master port."""
    q, dq, v = measure_master(s, grip_position_m, dt_s)
    took, gave = split_work(port_work_j(s.force_prev_n, dq))
    rx, inc = receive_total(s.rx, command.header.energy_total_j if command else None)
    led = s.ledger
    budget, diss = cap_tank(led.tank_j - gave + inc, p.max_j)
    f_des = clip(command.force_n, p.force_max_n) if command is not None else 0.0
    f_t = franken_limit(f_des, v, budget, dt_s)
    f = guard_force(f_t, budget, v, p.trigger_max_speed_m_s, dt_s)
    led = book(led, budget, port_in_j=took, port_out_j=gave, sent_j=took, received_j=inc,
               dissipated_j=diss)
    out = MasterOutput(force_n=f, grip_position_m=q, grip_velocity_m_s=v,
                       energy_total_j=led.sent_j, ledger=led, force_desired_n=f_des,
                       limited=f != f_des, tlc_damping_n_s_per_m=0.0)
    return MasterPortState(ledger=led, q_prev_m=q, force_prev_n=f, rx=rx), out


def init_controller(p: ControlParams) -> ControllerStoreState:
    """Nothing stored: the controller only relays."""
    return ControllerStoreState()


def step_controller(s: ControllerStoreState, p: ControlParams, master: MasterState | None,
                    hand: HandState | None, t_s: float,
                    dt_s: float) -> tuple[ControllerStoreState, ControllerOutput]:
    """Relay the largest totals seen; run the transparency layer."""
    rx_m, inc_m = receive_total(s.rx_master, master.header.energy_total_j if master else None)
    rx_h, inc_h = receive_total(s.rx_hand, hand.header.energy_total_j if hand else None)
    rho = p.energy_scale
    led = s.ledger  # in hand-side joules: relays exactly what it credits
    led = EnergyLedger(initial_j=led.initial_j, tank_j=led.tank_j, port_in_j=led.port_in_j,
                       port_out_j=led.port_out_j, sent_j=led.sent_j + rho * inc_m + inc_h,
                       received_j=led.received_j + rho * inc_m + inc_h,
                       dissipated_j=led.dissipated_j)
    ts, sp, force, mp, raw = transparency_commands(s, p, master, hand, dt_s)
    seq = s.seq + 1
    # power scaling: the hand's budget counts master joules times rho, and vice versa
    to_m, to_h = rx_h.seen_j / rho, rx_m.seen_j * rho
    fc, hc = make_commands(p, seq, t_s, force, to_m, sp, to_h)
    ns = ControllerStoreState(ledger=led, rx_master=rx_m, rx_hand=rx_h,
                              sent_to_master_j=to_m, sent_to_hand_j=to_h,
                              transparency=ts, seq=seq)
    return ns, ControllerOutput(force_command=fc, hand_command=hc, ledger=led,
                                max_pressure=mp, force_desired_n=raw)


def init_hand(p: ControlParams) -> HandPortState:
    """Budget ``W_S = E0``."""
    return HandPortState(ledger=EnergyLedger(initial_j=p.initial_j, tank_j=p.initial_j))


def step_hand(s: HandPortState, p: ControlParams, fingers: tuple[FingerState, ...],
              command: HandCommand | None, dt_s: float,
              t_s: float = math.nan) -> tuple[HandPortState, HandOutput]:
    """Passivity observer + set-point modulation at the hand port."""
    x, y_prev, d_j = sample_hand_port(s, p, fingers, dt_s)
    k, tmax = p.servo_stiffness_nm_per_rad, p.servo_torque_max_nm
    rx, inc = receive_total(s.rx, command.header.energy_total_j if command else None)
    led = s.ledger
    budget, diss = cap_tank(led.tank_j + inc, p.max_j)
    want = slew(desired_setpoints(command, y_prev), y_prev, p.servo_max_speed_rad_s * dt_s)
    y, dp, limited = pspm_project(want, y_prev, x, budget + d_j, k, tmax)
    e = dp - d_j
    took, gave = max(-e, 0.0), max(e, 0.0)
    led = book(led, budget - gave, port_in_j=took, port_out_j=gave, sent_j=took,
               received_j=inc, dissipated_j=diss)
    pre = command.preshape_rad if command is not None else p.preshape_rad
    out = HandOutput(setpoint_rad=y, preshape_rad=pre, energy_total_j=led.sent_j, ledger=led,
                     setpoint_desired_rad=want, limited=limited,
                     spring_energy_j=spring_energy_j(y, x, k, tmax))
    return HandPortState(ledger=led, x_prev=x, setpoint_prev=y, rx=rx), out
