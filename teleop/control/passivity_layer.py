"""The hand's passivity layer: passive set-position modulation (Lee and Huang 2010), and the
reservation of the environment-port layer (end of the module; ``hand_port = "object"``).

The position-servoed finger is modelled as a spring from the set-point ``y`` to the motor
angle ``x`` whose torque saturates at the servo's torque limit (``tau = K e`` for
``|e| <= e_s = tau_max / K``, ``tau_max sign(e)`` beyond), plus a damper ``B`` on ``xdot``
(``K``, ``tau_max``: upper bounds of the servo's stiffness and torque; ``B``: a lower bound
of its damping).  The servo spring's energy is the convex (Huber) potential
``P(e) = K e^2 / 2`` for ``|e| <= e_s``, ``tau_max (|e| - e_s / 2)`` beyond.

* Dissipation over a sample of length ``T`` in which ``x`` moved by ``dx``: by Cauchy-Schwarz
  ``integral B xdot^2 dt >= B |dx|^2 / T``; this lower bound is credited to the tank
  (``D(k)``).
* Moving the set-point from ``y(k-1)`` to ``y(k)`` at the measured ``x(k)`` changes the spring
  energy by ``dP = sum P(y(k) - x) - sum P(y(k-1) - x)``; the tank pays it.
* The new set-point is the desired one pulled back along the ray from ``x(k)`` until
  ``dP <= E`` (``E`` the energy the tank can spend).  For the quadratic potential this is
  exactly Lee and Huang's projection onto the ball of squared radius
  ``|y(k-1) - x|^2 + 2 E / K``; ``y = x`` (zero spring energy) is always affordable.

Hence ``tank + P + environment storage`` never exceeds its initial value plus the energy the
tank received: the hand plus its environment stay passive for any delay or loss, provided the
servo is no stiffer (and no stronger) than modelled and no less damped than ``B``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

Triple = tuple[float, float, float]


def servo_potential_j(e: float, stiffness: float, torque_max: float = math.inf) -> float:
    """Energy the (saturating) servo spring stretched by ``e`` can deliver through the
    tendon: zero for ``e <= 0`` (the tendon only pulls; see the module docstring)."""
    if e <= 0.0:
        return 0.0
    a = e
    e_s = torque_max / stiffness
    if a <= e_s:
        return 0.5 * stiffness * a * a
    return torque_max * (a - 0.5 * e_s)


def spring_energy_j(setpoint: Triple, x: Triple, stiffness: float,
                    torque_max: float = math.inf) -> float:
    """Total servo-spring energy of the three fingers."""
    return sum(servo_potential_j(a - b, stiffness, torque_max)
               for a, b in zip(setpoint, x, strict=True))


def dissipation_lower_bound_j(x: Triple, x_prev: Triple, damping: float,
                              dt_s: float) -> float:
    """``B |x - x_prev|^2 / T``: energy the servo damping dissipated at least."""
    if dt_s <= 0.0:
        return 0.0
    return damping * sum(max(a - b, 0.0) ** 2 for a, b in zip(x, x_prev, strict=True)) / dt_s


def largest_fraction(cost: Callable[[float], float], allowed: float,
                     steps: int = 60) -> float:
    """The largest ``lam`` in [0, 1] with ``cost(lam) <= allowed`` for a cost that grows with
    ``lam`` and ``cost(0) <= allowed`` (bisection, from below)."""
    lo, hi = 0.0, 1.0
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        if cost(mid) <= allowed:
            lo = mid
        else:
            hi = mid
    return lo


def pspm_project(desired: Triple, previous: Triple, x: Triple, budget_j: float,
                 stiffness: float, torque_max: float = math.inf) -> tuple[Triple, float, bool]:
    """Pull ``desired`` back towards ``x`` until affordable; return (set-point, dP, limited)."""
    p_prev = spring_energy_j(previous, x, stiffness, torque_max)
    allowed = p_prev + max(budget_j, 0.0)
    d = (desired[0] - x[0], desired[1] - x[1], desired[2] - x[2])

    def energy(lam: float) -> float:
        return sum(servo_potential_j(lam * v, stiffness, torque_max) for v in d)

    if energy(1.0) <= allowed:
        return desired, energy(1.0) - p_prev, False
    # only closing components (d > 0) store energy; energy(1) > allowed >= 0 means one exists
    n2 = sum(v * v for v in d if v > 0.0)
    lam_q = math.sqrt(2.0 * allowed / (stiffness * n2))  # quadratic-region solution
    if all(lam_q * v * stiffness <= torque_max for v in d):
        lam = lam_q * (1.0 - 1e-12)  # shrink a hair so rounding never overdraws the tank
    else:
        lam = largest_fraction(energy, allowed)
    y = (x[0] + lam * d[0], x[1] + lam * d[1], x[2] + lam * d[2])
    e_new = energy(lam)
    if e_new > allowed:  # rounding at the edge: fall back to the always-affordable x
        y, e_new = x, 0.0
    return y, e_new - p_prev, True


# ------------------------------------------------ environment-port accounting (hand_port=object)
def reservation_j(e: float, stiffness: float, torque_max: float,
                  tendon_stiffness: float) -> float:
    """Energy a finger could still push into the object with its set-point frozen ``e``
    ahead of the motor: the servo spring's potential plus the tendon's stretch at the servo's
    torque (``tau^2 / 2 K_t``, ``K_t`` a lower bound of the tendon stiffness at the joint)."""
    if e <= 0.0:
        return 0.0
    tau = min(stiffness * e, torque_max)
    return servo_potential_j(e, stiffness, torque_max) + 0.5 * tau * tau / tendon_stiffness


def hand_reservation_j(setpoint: Triple, x: Triple, stiffness: float, torque_max: float,
                       tendon_stiffness: float) -> float:
    """:func:`reservation_j` summed over the three fingers."""
    return sum(reservation_j(a - b, stiffness, torque_max, tendon_stiffness)
               for a, b in zip(setpoint, x, strict=True))


def reserve_project(desired: Triple, x: Triple, budget_j: float, stiffness: float,
                    torque_max: float, tendon_stiffness: float) -> tuple[Triple, bool]:
    """``desired`` pulled back along the ray from the measured ``x`` until its reservation
    fits in ``budget_j`` (``y = x`` reserves nothing and is always allowed)."""
    d = tuple(a - b for a, b in zip(desired, x, strict=True))

    def need(lam: float) -> float:
        return sum(reservation_j(lam * v, stiffness, torque_max, tendon_stiffness) for v in d)

    if need(1.0) <= budget_j:
        return desired, False
    lam = largest_fraction(need, budget_j) if budget_j > 0.0 else 0.0
    y = tuple(b + lam * v for b, v in zip(x, d, strict=True))
    return y, True  # type: ignore[return-value]
