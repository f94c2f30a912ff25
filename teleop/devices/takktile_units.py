"""Raw brain-board units <-> SI, the stock driver's conventions (pure functions).

Reference: reflex-hardware.md.  Motor ``k`` has an inversion ``inv`` (+1/-1), a motor zero
``zero_rad`` (raw * scale / ratio at joint angle 0, what calibration stores) and a
motor-to-joint ratio (1.42 fingers, 1.5 preshape):

* joint angle = inv * (raw * scale / ratio - zero); raw goal = (inv * joint + zero) * ratio /
  scale, clamped to the multi-turn range; on the wire a negative count wraps (uint16).
* moving speed = |v| * ratio / 0.01194 rad/s, + 1024 for the reverse direction, 0 -> 1.
* load (positive = pulling the tendon) = inv * (raw - 1023 if raw > 1023 else -raw).
* proximal encoder (AS5048A, 14 bit): 2 pi / 16383 rad per count; :func:`unwrap_counts`
  tracks the wrap.
"""

from __future__ import annotations

import math

from teleop.devices.dynamixel_tables import (
    P1_MULTI_TURN_MAX,
    P1_MULTI_TURN_MIN,
    P1_RAD_PER_COUNT,
    P1_RAD_S_PER_SPEED_UNIT,
)

RAD_PER_COUNT = P1_RAD_PER_COUNT  # 8 pi / 4095 (multi-turn, resolution divider 4)
RAD_S_PER_SPEED_UNIT = P1_RAD_S_PER_SPEED_UNIT  # 0.01194 rad/s at the shaft
ENCODER_COUNTS = 16384
ENCODER_RAD_PER_COUNT = 2.0 * math.pi / 16383.0
SPEED_REVERSE = 1024
LOAD_CW = 1023


def signed_counts(raw_u16: int) -> int:
    """A wire angle (uint16, a negative multi-turn count wrapped) as signed counts."""
    return raw_u16 - 65536 if raw_u16 > 32767 else raw_u16


def wire_counts(counts: int) -> int:
    """Signed counts clamped to the multi-turn range, as a uint16 for the wire."""
    return max(P1_MULTI_TURN_MIN, min(P1_MULTI_TURN_MAX, counts)) & 0xFFFF


def joint_from_raw(raw_u16: int, inv: int, zero_rad: float, ratio: float) -> float:
    """Joint angle (rad) of a motor reading ``raw_u16``."""
    return inv * (signed_counts(raw_u16) * RAD_PER_COUNT / ratio - zero_rad)


def raw_goal(joint_rad: float, inv: int, zero_rad: float, ratio: float) -> int:
    """The wire goal position (uint16) for ``joint_rad``."""
    return wire_counts(round((inv * joint_rad + zero_rad) * ratio / RAD_PER_COUNT))


def raw_speed(joint_speed_rad_s: float, ratio: float) -> int:
    """The wire moving speed for a signed joint speed (0 would mean full speed: sent as 1)."""
    units = min(1023, round(abs(joint_speed_rad_s) * ratio / RAD_S_PER_SPEED_UNIT))
    return max(1, units) + (SPEED_REVERSE if joint_speed_rad_s < 0 else 0)


def shaft_speed_from_raw(raw: int) -> float:
    """Signed shaft speed (rad/s) of a speed reading or setting (bit 10 = reverse)."""
    v = (raw & 0x3FF) * RAD_S_PER_SPEED_UNIT
    return -v if raw & SPEED_REVERSE else v


def load_from_raw(raw: int, inv: int) -> float:
    """Signed load (positive = pulling the tendon) of a Protocol 1.0 load reading."""
    return float(inv * (raw - LOAD_CW if raw > LOAD_CW else -raw))


def raw_load(load_pull_units: float, inv: int) -> int:
    """The load reading a servo with inversion ``inv`` reports for ``load_pull_units``."""
    signed = max(-LOAD_CW, min(LOAD_CW, round(inv * load_pull_units)))
    return signed + LOAD_CW if signed > 0 else -signed


def encoder_counts(angle_rad: float, offset_counts: int) -> int:
    """The 14-bit reading of a proximal encoder at ``angle_rad``."""
    return (offset_counts + round(angle_rad / ENCODER_RAD_PER_COUNT)) % ENCODER_COUNTS


def unwrap_counts(prev_unwrapped: int | None, raw: int) -> int:
    """Continuous counts: ``raw`` (0..16383) placed nearest ``prev_unwrapped``."""
    if prev_unwrapped is None:
        return raw
    step = (raw - prev_unwrapped) % ENCODER_COUNTS
    if step > ENCODER_COUNTS // 2:
        step -= ENCODER_COUNTS
    return prev_unwrapped + step
