"""Energy tank operations of the master's passivity layer (Franken et al. 2011).

Sign conventions: ``q`` is the trigger closing (m, grows as the operator squeezes) and the
displayed force ``F`` is positive when it resists closing, so the device pushes the trigger
with ``-F`` along ``q``.

* Exact port energy of a zero-order-held force (Stramigioli et al. 2005): the work the
  device did on the operator during the last sample is ``w(k) = -F(k-1) (q(k) - q(k-1))``;
  the tank pays it: ``H <- H - w``.  No velocity estimate is involved.
* Franken's limiter: with ``v`` the last sample's velocity, the force the transparency layer
  wants would deliver ``-F v T`` next sample; if that exceeds ``H - H_min``, ``|F|`` is cut
  to ``(H - H_min) / (|v| T)`` keeping the sign of the desired force.
* Hard guard (ours): ``|F| <= H / (max(v_max, |v|) T)`` so that even the worst motion the
  trigger can make in one sample (``|dq| <= v_max T``) cannot draw the tank below zero.
* Tank level controller: ``d = min(alpha max(H_d - H, 0), d_max, m / (2 T))``,
  ``F_tlc = d v`` (a damper on the operator's motion whose dissipated energy refills the
  tank).  The ``m / (2 T)`` cap keeps ``d T / m <= 1/2``: the sampled damper with a one-sample
  velocity lag stays well-damped instead of generating energy itself.
* Upper limit: anything above ``H_max`` is dissipated.  Energy sent on is a fraction of the
  surplus above the reserve: ``beta max(H - H_reserve, 0)``, never negative.
"""

from __future__ import annotations

import math


def port_work_j(force_prev_n: float, dq_m: float) -> float:
    """Work the device did on the operator over the last sample (positive = delivered)."""
    return -force_prev_n * dq_m


def split_work(work_j: float) -> tuple[float, float]:
    """(taken from the port, delivered to the port) for one sample's work."""
    return (max(-work_j, 0.0), max(work_j, 0.0))


def tlc_damping(tank_j: float, desired_j: float, gain: float, damping_max: float,
                mass_kg: float, dt_s: float) -> float:
    """Tank level controller damping (N s/m), capped so the sampled damper stays passive."""
    cap = min(damping_max, 0.5 * mass_kg / dt_s) if dt_s > 0 else 0.0
    return min(gain * max(desired_j - tank_j, 0.0), cap)


def franken_limit(force_n: float, velocity_m_s: float, budget_j: float,
                  dt_s: float) -> float:
    """Scale ``force_n`` so the energy it would deliver next sample stays within ``budget_j``."""
    delivered = -force_n * velocity_m_s * dt_s
    if delivered <= max(budget_j, 0.0) or delivered <= 0.0:
        return force_n
    mag = max(budget_j, 0.0) / (abs(velocity_m_s) * dt_s)
    return math.copysign(min(abs(force_n), mag), force_n)


def guard_force(force_n: float, tank_j: float, velocity_m_s: float, max_speed_m_s: float,
                dt_s: float) -> float:
    """Limit ``|force_n|`` so no motion within the speed bound can draw the tank below 0."""
    step = max(max_speed_m_s, abs(velocity_m_s)) * dt_s
    if step <= 0.0:
        return force_n
    mag = max(tank_j, 0.0) / step
    return math.copysign(min(abs(force_n), mag), force_n)


def cap_tank(tank_j: float, max_j: float) -> tuple[float, float]:
    """(tank, dissipated): the surplus above ``max_j`` is thrown away."""
    if tank_j > max_j:
        return max_j, tank_j - max_j
    return tank_j, 0.0


def quantum_j(tank_j: float, reserve_j: float, fraction: float) -> float:
    """Energy to send this sample: a fraction of the surplus above the reserve (>= 0)."""
    return fraction * max(tank_j - reserve_j, 0.0)
