"""Hand side of model-mediated rendering: a contact model per finger, estimated online.

The model is the settled (static) relation between a finger's set-point ``y`` and the peak
pressure ``P`` its cells read, the map the operator would feel at zero delay once the servo
has settled::

    P(y) = k * max(y - theta_c, 0)

* ``theta_c``, the contact angle, in set-point terms: the motor angle ``x`` at which the
  pressure rises through ``contact_pressure`` (closing), plus the servo's free-motion offset
  ``a`` (the settled ``y - x`` while touching nothing, a first-order average over settled
  free samples).  A new touch re-measures it: an object that moved is noticed at its next
  touch.  On a soft object the threshold means a deeper press, so the angle reads late by
  about ``contact_pressure / k_e`` (0.1 rad at 400 units/rad); the settled map through it
  still holds at the grasp (``k`` absorbs it).  ``y`` is the set-point averaged over
  ``SETPOINT_TAU_S``: the servo does not follow the operator's tremor; neither does the
  estimate.
* ``k``, the stiffness: the forgetting average (time constant ``memory_s``) of the settled
  secant ``P / d``, ``d = y - theta_c``, over *settled* samples (set-point within
  ``HELD_TOL_RAD`` of its average, motor angle slower than ``static_speed_rad_s``, a
  sample-to-sample change ``|dP| < settle_rate * P * dt + settle_noise``: the noise term lets a
  light grasp settle): ``k = sum w (P / d) dt / sum w dt``.  Every settled second counts the
  same, whatever the grasp's depth, so ``k`` is the secant where the operator has been holding
  over the last ``memory_s``.  Real objects stiffen (a compliant skin over a rigid core): a
  least-squares line through ``(theta_c, 0)`` (``sum w P d / sum w d^2``) weights a deep
  squeeze by ``d^2`` and kept rendering its steep secant for seconds after the operator had
  eased to a light hold (the soft operator on the block at 1 s one-way: felt/true 1.8).  Only
  settled samples count: the servo takes ~0.5 s to settle on an object and its speed limit
  lags a fast set-point, so the moving part of a grasp (pressure far off the static map) would
  bias ``k``.
* From a finger's first touch until ``evidence_s`` of settled samples exist, ``k`` is
  ``prior_stiffness`` (so the operator feels the contact one round trip after the touch, not
  after the grasp has settled); then the fit, while it stays finite and ``0 < k <=
  stiffness_max``.  A diverged or non-finite estimate is dropped and counted (``fallbacks``),
  and the controller falls back to the delayed measured force.
* Removal: a finger more than ``removal_margin_rad`` past its contact angle (motor angle) with
  no pressure has lost its object: the model is dropped (the master then ramps it out).

Pure step functions; the hand's two-layer step runs one per finger (see
:func:`teleop.control.two_layer.step_hand`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from teleop.config.control import ContactModelConfig
from teleop.frozen import fast_init


@fast_init
@dataclass(frozen=True, slots=True)
class FingerModel:
    """One finger's estimate and its sufficient statistics."""

    contact_rad: float = math.nan  # theta_c (nan: not measured yet)
    stiffness: float = 0.0  # k, pressure units per rad (0: no valid model)
    s_secant: float = 0.0  # forgetting sum over settled samples: sum w (P / d) dt
    evidence_s: float = 0.0  # forgetting sum of settled time: sum w dt
    free_offset_rad: float = 0.0  # a: settled y - x touching nothing
    touching: bool = False
    y_prev: float = math.nan  # the averaged set-point (SETPOINT_TAU_S)
    x_prev: float = math.nan
    p_prev: float = math.nan
    fallbacks: int = 0  # diverged / non-finite estimates dropped

    @property
    def valid(self) -> bool:
        return self.stiffness > 0.0 and math.isfinite(self.contact_rad)


#: time constant of the averaged set-point (s): about the servo's settling on an object
SETPOINT_TAU_S = 0.2
#: a set-point within this of its average counts as held (rad): tremor, not a move
HELD_TOL_RAD = 0.03


def _forget(dt_s: float, memory_s: float) -> float:
    return math.exp(-max(dt_s, 0.0) / memory_s)


def _dropped(m: FingerModel, *, counted: bool) -> FingerModel:
    """No model: statistics cleared (the free offset is the servo's, it stays)."""
    return FingerModel(free_offset_rad=m.free_offset_rad, touching=m.touching, y_prev=m.y_prev,
                       x_prev=m.x_prev, p_prev=m.p_prev,
                       fallbacks=m.fallbacks + (1 if counted else 0))


def step_finger_model(m: FingerModel, c: ContactModelConfig, y_rad: float, x_rad: float,
                      pressure: float, dt_s: float) -> FingerModel:
    """One hand sample: ``y_rad`` the set-point in force over the sample that ended now,
    ``x_rad`` the motor angle, ``pressure`` the finger's peak pressure."""
    if not (math.isfinite(y_rad) and math.isfinite(x_rad) and math.isfinite(pressure)):
        return m
    first = not math.isfinite(m.y_prev)
    # the set-point as the servo sees it: averaged over the servo's settling time, so the
    # operator's tremor around a held grasp does not count as motion
    g = 1.0 - _forget(dt_s, SETPOINT_TAU_S)
    y_avg = y_rad if first else m.y_prev + g * (y_rad - m.y_prev)
    held = not first and abs(y_rad - y_avg) <= HELD_TOL_RAD
    still = held and abs(x_rad - m.x_prev) <= c.static_speed_rad_s * dt_s
    touching = pressure >= (0.5 * c.contact_pressure if m.touching else c.contact_pressure)
    nxt = replace(m, touching=touching, y_prev=y_avg, x_prev=x_rad, p_prev=pressure)
    if not touching:
        if still:  # settled in free motion: the servo's offset
            g = 1.0 - _forget(dt_s, c.memory_s)
            off = m.free_offset_rad + g * (y_rad - x_rad - m.free_offset_rad)
            nxt = replace(nxt, free_offset_rad=off)
        if math.isfinite(m.contact_rad) and x_rad > m.contact_rad + c.removal_margin_rad:
            return _dropped(nxt, counted=False)  # past the object without touching it
        return nxt
    if not m.touching:  # a new touch: where the object is now (the prior until a fit)
        k = m.stiffness if m.evidence_s >= c.evidence_s else c.prior_stiffness
        return replace(nxt, contact_rad=x_rad + m.free_offset_rad, stiffness=k)
    settled = still and (abs(pressure - m.p_prev)
                         <= c.settle_rate_per_s * pressure * dt_s + c.settle_noise)
    d = y_avg - m.contact_rad
    if not (settled and math.isfinite(d) and d >= c.min_deflection_rad):
        return nxt
    lam = _forget(dt_s, c.memory_s)
    s_secant = lam * m.s_secant + pressure / d * dt_s
    ev = lam * m.evidence_s + dt_s
    k = s_secant / ev if ev > 0.0 else math.nan
    if not (math.isfinite(k) and 0.0 < k <= c.stiffness_max):
        return _dropped(nxt, counted=True)
    return replace(nxt, s_secant=s_secant, evidence_s=ev,
                   stiffness=k if ev >= c.evidence_s else m.stiffness)


def step_models(ms: tuple[FingerModel, ...] | None, c: ContactModelConfig,
                y: tuple[float, ...], x: tuple[float, ...], pressures: tuple[float, ...],
                dt_s: float) -> tuple[FingerModel, ...]:
    """:func:`step_finger_model` for every finger."""
    prev = ms if ms is not None else tuple(FingerModel() for _ in y)
    return tuple(step_finger_model(m, c, yi, xi, pi, dt_s)
                 for m, yi, xi, pi in zip(prev, y, x, pressures, strict=True))


def model_wire(ms: tuple[FingerModel, ...] | None,
               held_back_rad: tuple[float, ...] = ()) -> tuple[float, ...]:
    """``(contact_rad, stiffness)`` per finger, flattened (stiffness 0: no model).

    ``held_back_rad``: per finger, how far the hand's tank holds its set-point back from the
    one it would apply (never negative); a valid model's contact angle goes on the wire moved
    out by it.  The master renders ``k (s - c)`` at the set-point ``s`` its trigger asks
    for while the hand presses ``k (y - c)`` at the applied ``y``; moved by ``s - y``, the
    model renders what the hand presses, so a starved hand is not felt as a firm grasp."""
    out: list[float] = []
    for i, m in enumerate(ms or ()):
        if not m.valid:
            out += [0.0, 0.0]
            continue
        gap = held_back_rad[i] if i < len(held_back_rad) else 0.0
        out += [m.contact_rad + gap if gap > 0.0 else m.contact_rad, m.stiffness]
    out += [0.0] * (6 - len(out))
    return tuple(out[:6])
