"""``direct``: the seed report's baseline (Lammers 2017; report section 5.1).

Trigger position -> finger set-points, maximum pressure -> trigger force (the same
transparency layer as ``two-layer``), no passivity layer, no energy exchanged (all energy
totals stay 0).  The ledgers still account the port energy (master: exact ZOH work; hand:
the servo-spring model of :mod:`teleop.control.passivity_layer`) with ``tank_j = in - out``,
so a negative ``tank_j`` measures the energy the loop has generated.  Expected to go
unstable with delay against a stiff contact (see :mod:`teleop.control.stability_limit`).
"""

from __future__ import annotations

import math

from teleop.control.energy_channel import EnergyLedger, book
from teleop.control.energy_tank import port_work_j, split_work
from teleop.control.interface import ControllerOutput, ControlParams, HandOutput, MasterOutput
from teleop.control.passivity_layer import spring_energy_j
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
)
from teleop.control.two_layer_master import (
    MasterPortState,
    measure_master,
)
from teleop.messages import FingerState, ForceCommand, HandCommand, HandState, MasterState


def init_master(p: ControlParams) -> MasterPortState:
    """No tank."""
    return MasterPortState(ledger=EnergyLedger())


def step_master(s: MasterPortState, p: ControlParams, grip_position_m: float,
                command: ForceCommand | None, dt_s: float) -> tuple[MasterPortState,
                                                                    MasterOutput]:
    """Display the commanded force (clipped); account the port energy."""
    q, dq, v = measure_master(s, grip_position_m, dt_s)
    took, gave = split_work(port_work_j(s.force_prev_n, dq))
    led = s.ledger
    led = book(led, led.tank_j + took - gave, port_in_j=took, port_out_j=gave)
    f = clip(command.force_n, p.force_max_n) if command is not None else 0.0
    out = MasterOutput(force_n=f, grip_position_m=q, grip_velocity_m_s=v, energy_total_j=0.0,
                       ledger=led, force_desired_n=f, limited=False, tlc_damping_n_s_per_m=0.0)
    return MasterPortState(ledger=led, q_prev_m=q, force_prev_n=f, rx=s.rx), out


def init_controller(p: ControlParams) -> ControllerStoreState:
    """Only the force filter."""
    return ControllerStoreState()


def step_controller(s: ControllerStoreState, p: ControlParams, master: MasterState | None,
                    hand: HandState | None, t_s: float,
                    dt_s: float) -> tuple[ControllerStoreState, ControllerOutput]:
    """Transparency layer only."""
    ts, sp, force, mp, raw = transparency_commands(s, p, master, hand, dt_s)
    seq = s.seq + 1
    fc, hc = make_commands(p, seq, t_s, force, 0.0, sp, 0.0)
    ns = ControllerStoreState(ledger=s.ledger, rx_master=s.rx_master, rx_hand=s.rx_hand,
                              sent_to_master_j=s.sent_to_master_j,
                              sent_to_hand_j=s.sent_to_hand_j, transparency=ts, seq=seq,
                              adapt=s.adapt, model_since=s.model_since)
    return ns, ControllerOutput(force_command=fc, hand_command=hc, ledger=s.ledger,
                                max_pressure=mp, force_desired_n=raw)


def init_hand(p: ControlParams) -> HandPortState:
    """No tank."""
    return HandPortState(ledger=EnergyLedger())


def step_hand(s: HandPortState, p: ControlParams, fingers: tuple[FingerState, ...],
              command: HandCommand | None, dt_s: float,
              t_s: float = math.nan) -> tuple[HandPortState, HandOutput]:
    """Pass the commanded set-points through; account the modelled port energy."""
    x, y_prev, d_j = sample_hand_port(s, p, fingers, dt_s)
    k, tmax = p.servo_stiffness_nm_per_rad, p.servo_torque_max_nm
    y = desired_setpoints(command, y_prev)
    e = spring_energy_j(y, x, k, tmax) - spring_energy_j(y_prev, x, k, tmax) - d_j
    led = s.ledger
    led = book(led, led.tank_j - e, port_in_j=max(-e, 0.0), port_out_j=max(e, 0.0))
    pre = command.preshape_rad if command is not None else p.preshape_rad
    out = HandOutput(setpoint_rad=y, preshape_rad=pre, energy_total_j=0.0, ledger=led,
                     setpoint_desired_rad=y, limited=False,
                     spring_energy_j=spring_energy_j(y, x, k, tmax))
    return HandPortState(ledger=led, x_prev=x, setpoint_prev=y, rx=s.rx), out
