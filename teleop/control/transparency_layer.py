"""Transparency layer (report chapter 5.2): trigger opening -> finger set-points, and
per-finger maximum pressure -> the force displayed on the trigger.

* Set-points: ``s = clip(q / travel, 0, 1)`` (``q`` the trigger closing, 0 = open) and for
  every enabled finger ``theta = open + (closed - open) * s ** exponent``; disabled fingers
  stay at ``open``.
* Force: ``p_i = max_j pressure_ij`` for every enabled finger (the maximum, not the average:
  a cylinder loads only a few of the nine cells), combined across fingers (``max`` | ``mean``
  | ``sum``), clipped at zero, scaled by ``force_per_pressure_n``, low-passed (first order,
  exact discretisation ``y += (1 - exp(-2 pi f dt)) (u - y)``) and clipped to
  ``+-force_max_n``.

It knows nothing about energy: the passivity layers below limit what it asks for.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from teleop.control.interface import ControlParams
from teleop.control.memo import last_result
from teleop.frozen import fast_init
from teleop.messages import FingerState

Triple = tuple[float, float, float]


@fast_init
@dataclass(frozen=True, slots=True)
class TransparencyState:
    """The displayed-force filter's state."""

    force_n: float = 0.0


def grip_to_setpoints(grip_position_m: float, p: ControlParams) -> Triple:
    """Finger set-points (rad) for a trigger closing of ``grip_position_m``."""
    s = grip_position_m / p.trigger_travel_m if math.isfinite(grip_position_m) else 0.0
    # min(max(s, 0.0), 1.0) as the comparisons max and min make (the same floats)
    s = 0.0 if s < 0.0 else s
    s = (1.0 if s > 1.0 else s) ** p.map_exponent
    closed = p.open_angle_rad + (p.closed_angle_rad - p.open_angle_rad) * s
    on = p.finger_enable
    if on[0] and on[1] and on[2]:
        return (closed, closed, closed)
    return tuple(closed if on[i] else p.open_angle_rad  # type: ignore[return-value]
                 for i in range(3))


@last_result
def max_pressures(fingers: tuple[FingerState, ...], p: ControlParams) -> Triple:
    """The largest pressure on each enabled finger (0 for disabled or missing fingers)."""
    out = [0.0, 0.0, 0.0]
    for i, f in enumerate(fingers[:3]):
        if p.finger_enable[i] and f.pressure:
            m = max(f.pressure)
            out[i] = m if math.isfinite(m) else 0.0
    return (out[0], out[1], out[2])


@last_result
def combined_force_n(max_p: Triple, p: ControlParams) -> float:
    """Unfiltered displayed force from the per-finger maxima, tactile noise removed
    (:func:`deadband`)."""
    return deadband(max(combine(max_p, p), 0.0), p.pressure_deadband) * p.force_per_pressure_n


def deadband(pressure: float, band: float) -> float:
    """``pressure`` with the sensor's noise band removed: 0 up to ``band``, the pressure itself
    from ``2 band`` on, a straight line between (continuous, no step the operator could feel).

    Free-air tactile noise (the peak of 27 noisy cells, a few units) would otherwise reach the
    trigger as a buzzing force the operator's hand resonates with."""
    if pressure >= 2.0 * band:
        return pressure
    return 2.0 * (pressure - band) if pressure > band else 0.0


def combine(per_finger: Triple, p: ControlParams) -> float:
    """The enabled fingers' values combined by ``force_combine`` (0 with none enabled)."""
    on = p.finger_enable
    vals = (list(per_finger) if on[0] and on[1] and on[2] and len(on) == 3
            else [v for v, e in zip(per_finger, on[:3], strict=True) if e])
    if not vals:
        return 0.0
    if p.force_combine == "max":
        return max(vals)
    if p.force_combine == "sum":
        return sum(vals)
    return sum(vals) / len(vals)


def clip(x: float, limit: float) -> float:
    """``x`` limited to ``[-limit, limit]`` (NaN -> 0)."""
    if not math.isfinite(x):
        return 0.0 if math.isnan(x) else math.copysign(limit, x)
    lo = -limit  # min(max(x, -limit), limit) as the comparisons they make (the same floats)
    x = lo if lo > x else x
    return limit if limit < x else x


def lowpass(prev: float, u: float, cutoff_hz: float, dt_s: float) -> float:
    """One step of an exactly discretised first-order low-pass."""
    a = 1.0 - math.exp(-2.0 * math.pi * cutoff_hz * max(dt_s, 0.0))
    return prev + a * (u - prev)


def transparency_force(state: TransparencyState, p: ControlParams,
                       fingers: tuple[FingerState, ...] | None, dt_s: float,
                       gain: float = 1.0) -> tuple[TransparencyState, float, Triple, float]:
    """Filtered, clipped display force; returns (state, force_n, max_pressures, unfiltered).

    ``gain`` scales the force before the filter (the delay-aware schedule of ``two-layer``,
    :mod:`teleop.control.delay_adapt`; 1 elsewhere)."""
    if fingers is None:
        mp: Triple = (0.0, 0.0, 0.0)
    else:
        mp = max_pressures(fingers, p)
    raw = gain * combined_force_n(mp, p)
    f = clip(lowpass(state.force_n, raw, p.force_filter_hz, dt_s), p.force_max_n)
    return TransparencyState(force_n=f), f, mp, raw
