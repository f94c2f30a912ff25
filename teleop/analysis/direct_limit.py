"""Which linearised loop corresponds to the simulated direct loop, and its delay limit.

:mod:`teleop.control.stability_limit` gives the largest stable round-trip delay of the loop
``Z_m(s) + K_f G P_s(s) F(s) e^{-sT} = 0``.  This module fills its parameters from the
configuration and from the hand itself, and converts the round trip into the sweep's one-way
master<->controller delay.

What the simulated loop is, element by element:

* ``Z_m = m s^2 + b s + k_h``: the virtual operator's finger on the trigger (mass from
  ``master.virtual.mass_kg``, stiffness and damping of the grasp style);
* ``G``: the transparency map, ``(closed - open) / travel`` rad per metre;
* ``P_s``: finger set-point -> pressure at the hand, in contact at the hold's operating point.
  The MX-28 servo is a P controller (``kp`` effort units per shaft rad) driving a motor whose
  viscous damping ``D(u)`` *falls with the effort u* (seed Table 4.1: 742 -> 472 units per
  rad/s from 50 to 200 units).  With the finger and object as a spring behind it, the hand is
  first order: ``P_s = K0 / (tau s + 1)``, ``tau = D r_m / kp`` where ``r_m`` is the static
  motor-angle / set-point ratio (``kp / (kp + k_load)``).  ``K0`` and ``r_m`` are static, so
  they are measured with small set-point steps on the hand at the operating point.  ``tau``
  depends on amplitude: a grasp closing at the operator's speed drives the servo to its
  torque limit (``u = max effort``), where the damping and so ``tau`` are smallest - the
  least stable linearisation, used for the prediction (``effort_units``).  Small-signal
  linearisation (``D`` at a few units plus Coulomb friction) would give ``tau`` two to three
  times larger and a much longer (wrong) limit: the simulated loop is *subcritical*, the
  grasp transient is large.
* ``K_f``: ``force_per_pressure_n``; ``F``: the displayed-force low-pass.
* ``T``: ``2 d`` plus the loop's own latencies: the hand service samples and holds at its
  state rate (half a period for the command, half for the state), plus one tick each of
  master and controller, plus the controller<->hand link delays.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from teleop.config import TeleopConfig
from teleop.control.stability_limit import DirectLoopParams, predicted_max_stable_delay_s
from teleop.devices.base import HandBackend
from teleop.messages import HandCommand, Header

__all__ = ["HandLinearisation", "identify_hand", "direct_loop_params", "intrinsic_delay_s",
           "DirectPrediction", "predict_direct_limit"]


@dataclass(frozen=True, slots=True)
class HandLinearisation:
    """The hand in contact at an operating point: ``P_s = K0 / (tau s + 1)``."""

    setpoint_rad: float  # operating point (joint set-point)
    pressure: float  # max pressure there (raw units)
    gain_pressure_per_rad: float  # K0
    motor_ratio: float  # r_m: static motor angle change per set-point change
    tau_s: float


@dataclass(frozen=True, slots=True)
class DirectPrediction:
    """The predicted largest stable delay of direct control and what it rests on."""

    one_way_s: float  # largest stable one-way master<->controller delay
    round_trip_s: float  # T_max of the linearised loop
    intrinsic_s: float  # loop latency present at zero configured delay
    loop: DirectLoopParams
    hand: HandLinearisation


def _cmd(sp: float) -> HandCommand:
    return HandCommand(header=Header(seq=0, t_s=0.0, energy_total_j=0.0),
                       finger_setpoint_rad=(sp, sp, sp), preshape_rad=0.0)


def _finger_reading(hand: HandBackend, t_s: float, finger: int) -> tuple[float, float]:
    f = hand.read(t_s).fingers[finger]
    return max(f.pressure), f.motor_angle_rad


def identify_hand(cfg: TeleopConfig, hand: HandBackend, *, damping_units: float,
                  kp_units_per_rad: float, operator_stiffness_n_per_m: float,
                  finger: int = 0, step_rad: float = 0.02, dt_s: float = 1e-3) -> HandLinearisation:
    """Find the hold's operating point on ``hand`` and linearise the hand there.

    The operating point is the zero-delay equilibrium of the direct loop with the operator
    holding at ``closed_fraction`` of the travel: ``k_h (x_ref - x) = K_f p(G x)``, reached by
    a slow relaxation on the hand.  ``K0`` and ``r_m`` come from a ``step_rad`` set-point step
    there; ``tau = damping_units * r_m / kp_units_per_rad``.
    """
    tr, mv = cfg.controller.transparency, cfg.master.virtual
    travel = cfg.master.travel_m
    g = (tr.closed_angle_rad - tr.open_angle_rad) / travel
    x_ref = mv.closed_fraction * travel
    hand.start()
    t, sp = 0.0, tr.open_angle_rad
    relax_s = 1.0
    for _ in range(int(8.0 / dt_s)):
        t += dt_s
        p, _ = _finger_reading(hand, t, finger)
        force = min(tr.force_per_pressure_n * p, cfg.master.force_max_n)
        x = min(max(x_ref - force / operator_stiffness_n_per_m, 0.0), travel)
        sp += dt_s / relax_s * (tr.open_angle_rad + g * x - sp)
        hand.apply(_cmd(sp))
    t += 4.0
    p0, m0 = _finger_reading(hand, t, finger)
    hand.apply(_cmd(sp + step_rad))
    t += 6.0
    p1, m1 = _finger_reading(hand, t, finger)
    hand.close()
    r_m = (m1 - m0) / step_rad
    return HandLinearisation(setpoint_rad=sp, pressure=p0,
                             gain_pressure_per_rad=(p1 - p0) / step_rad, motor_ratio=r_m,
                             tau_s=damping_units * r_m / kp_units_per_rad)


def direct_loop_params(cfg: TeleopConfig, hand: HandLinearisation, *,
                       operator_stiffness_n_per_m: float, operator_damping_n_s_per_m: float,
                       servo_stiffness_nm_per_rad: float) -> DirectLoopParams:
    """The linearised loop's parameters (``P_s`` in servo/contact form, same K0 and tau)."""
    tr = cfg.controller.transparency
    k = servo_stiffness_nm_per_rad
    r_m = min(max(hand.motor_ratio, 1e-3), 1.0 - 1e-6)
    k_e = k * (1.0 / r_m - 1.0)  # load stiffness behind the servo, joint side
    contact_torque_per_rad = k * k_e / (k + k_e)
    return DirectLoopParams(
        mass_kg=cfg.master.virtual.mass_kg, damping_n_s_per_m=operator_damping_n_s_per_m,
        stiffness_n_per_m=operator_stiffness_n_per_m,
        position_gain_rad_per_m=(tr.closed_angle_rad - tr.open_angle_rad) / cfg.master.travel_m,
        servo_stiffness_nm_per_rad=k, servo_damping_nm_s_per_rad=hand.tau_s * (k + k_e),
        contact_stiffness_nm_per_rad=k_e,
        force_gain_n_per_nm=tr.force_per_pressure_n * hand.gain_pressure_per_rad
        / contact_torque_per_rad,
        filter_hz=tr.force_filter_hz)


def intrinsic_delay_s(cfg: TeleopConfig) -> float:
    """Round-trip latency at zero configured master<->controller delay."""
    ch = cfg.links.controller_hand
    ch_back = ch.delay_s if ch.backward_delay_s is None else ch.backward_delay_s
    return (1.0 / cfg.hand.state_rate_hz + 1.0 / cfg.master.rate_hz
            + 1.0 / cfg.controller.rate_hz + ch.delay_s + ch_back)


def predict_direct_limit(cfg: TeleopConfig, hand: HandLinearisation, *,
                         operator_stiffness_n_per_m: float, operator_damping_n_s_per_m: float,
                         servo_stiffness_nm_per_rad: float) -> DirectPrediction:
    """Largest stable one-way delay: ``(T_max - intrinsic) / 2`` (0 when T_max < intrinsic)."""
    loop = direct_loop_params(cfg, hand, operator_stiffness_n_per_m=operator_stiffness_n_per_m,
                              operator_damping_n_s_per_m=operator_damping_n_s_per_m,
                              servo_stiffness_nm_per_rad=servo_stiffness_nm_per_rad)
    t_max = predicted_max_stable_delay_s(loop)
    intr = intrinsic_delay_s(cfg)
    one_way = max(0.0, (t_max - intr) / 2.0) if math.isfinite(t_max) else math.inf
    return DirectPrediction(one_way, t_max, intr, loop, hand)


HandFactory = Callable[[], HandBackend]
