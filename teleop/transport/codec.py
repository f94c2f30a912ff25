"""msgpack encoding and validating decoding of every message in :mod:`teleop.messages`.

Wire format: one msgpack array ``[kind, version, seq, t_s, energy_total_j, *fields]`` with
``kind`` a small integer per message type (:data:`KINDS`); floats travel as float64 so a
round trip is exact.  :func:`decode` checks, in order: bytes type, size cap, msgpack
well-formedness, shape, kind, schema version, header fields, then every field's type,
finiteness and physical range, and raises :class:`~teleop.errors.DecodeError` with one of
the stable tags in :data:`REASONS`.  Control loops use
:class:`~teleop.transport.safe_decoder.SafeDecoder`, which never raises.
"""

from __future__ import annotations

import math
from typing import Any

import msgpack

from teleop.errors import DecodeError
from teleop.messages import (
    N_FINGERS,
    N_PRESSURE,
    SCHEMA_VERSION,
    FingerState,
    ForceCommand,
    HandCommand,
    HandMode,
    HandState,
    Header,
    MasterState,
    Message,
)

#: Largest accepted encoded message [bytes] (a HandState is ~560 bytes).
MAX_MESSAGE_BYTES = 2048

#: Every reason tag :func:`decode` can raise.
REASONS: tuple[str, ...] = (
    "not_bytes", "too_large", "malformed", "bad_shape", "unknown_kind", "unexpected_kind",
    "bad_version", "bad_type", "not_finite", "out_of_range",
)

# Physical bounds (inclusive).  Generous around the ReFlex/trigger limits so that valid data
# from the simulation or hardware is never rejected, but tight enough to stop garbage.
GRIP_POSITION_RANGE_M = (-0.01, 0.05)
GRIP_VELOCITY_RANGE_M_S = (-10.0, 10.0)
FORCE_RANGE_N = (-100.0, 100.0)
FINGER_ANGLE_RANGE_RAD = (-math.pi, 2.0 * math.pi)  # travel 3.6 rad
PRESHAPE_RANGE_RAD = (-math.pi, math.pi)  # travel 1.75 rad
LOAD_RANGE_UNITS = (-2048.0, 2048.0)  # Dynamixel present load is +-1023
FORCE_UNITS_RANGE = (-4096.0, 4096.0)
PRESSURE_RANGE = (-1.0e5, 1.0e5)
TIME_RANGE_S = (0.0, 1.0e10)
ENERGY_RANGE_J = (0.0, 1.0e12)
MODEL_STIFFNESS_RANGE = (0.0, 1.0e4)  # N per rad of set-point (trigger force)
CONTACT_STIFFNESS_RANGE = (0.0, 1.0e6)  # pressure units per rad
ECHO_RANGE_S = (-1.0, 1.0e10)  # echoed peer timestamp; negative = nothing received yet
HELD_RANGE_S = (0.0, 1.0e10)  # how long the echoed message had been held
SEQ_MAX = 2**63 - 1

KINDS: dict[type, int] = {MasterState: 1, ForceCommand: 2, HandCommand: 3, HandState: 4}
_TYPE_OF_KIND = {v: k for k, v in KINDS.items()}
_N_FIELDS = {MasterState: 4, ForceCommand: 2, HandCommand: 5, HandState: 7}
_HEAD = 5  # kind, version, seq, t_s, energy_total_j
_FINGER_FIELDS = 6


# ----------------------------------------------------------------------------- encode

def _finger_to_wire(f: FingerState) -> list[Any]:
    return [float(f.proximal_rad), float(f.distal_rad), float(f.motor_angle_rad),
            float(f.load_units), [float(p) for p in f.pressure], [bool(c) for c in f.contact]]


def _fields(msg: Message) -> list[Any]:
    if isinstance(msg, MasterState):
        return [float(msg.grip_position_m), float(msg.grip_velocity_m_s), float(msg.echo_t_s),
                float(msg.echo_held_s)]
    if isinstance(msg, ForceCommand):
        return [float(msg.force_n), [float(x) for x in msg.model]]
    if isinstance(msg, HandCommand):
        return [[float(x) for x in msg.finger_setpoint_rad], float(msg.preshape_rad),
                int(msg.mode), [float(x) for x in msg.finger_force_units],
                float(msg.hand_echo_t_s)]
    if isinstance(msg, HandState):
        return [[_finger_to_wire(f) for f in msg.fingers], float(msg.preshape_rad),
                float(msg.echo_t_s), float(msg.echo_held_s),
                [float(x) for x in msg.contact_model], int(msg.servo_fault_trips),
                bool(msg.servo_safe)]
    raise TypeError(f"encode: not a teleop message: {type(msg).__name__}")


def encode(msg: Message) -> bytes:
    """Encode ``msg`` as msgpack (no validation: :func:`decode` validates)."""
    h = msg.header
    wire = [KINDS[type(msg)], int(h.version), int(h.seq), float(h.t_s),
            float(h.energy_total_j), *_fields(msg)]
    return msgpack.packb(wire, use_bin_type=True)  # type: ignore[no-any-return]


# ----------------------------------------------------------------------------- decode

def _num(v: Any, name: str, lo: float, hi: float) -> float:
    if type(v) is float and lo <= v <= hi:  # the valid case, at once (NaN fails the test)
        return v
    return _num_checked(v, name, lo, hi)


def _num_checked(v: Any, name: str, lo: float, hi: float) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise DecodeError("bad_type", f"{name} must be a number, got {type(v).__name__}")
    x = float(v) if not isinstance(v, int) or abs(v) < 2**53 else math.inf
    if not math.isfinite(x):
        raise DecodeError("not_finite", name)
    if not lo <= x <= hi:
        raise DecodeError("out_of_range", f"{name}={x!r} not in [{lo}, {hi}]")
    return x


def _list(v: Any, name: str, n: int) -> list[Any]:
    if not isinstance(v, list):
        raise DecodeError("bad_type", f"{name} must be an array, got {type(v).__name__}")
    if len(v) != n:
        raise DecodeError("bad_shape", f"{name} has {len(v)} items, expected {n}")
    return v


def _floats_within(v: Any, n: int, lo: float, hi: float) -> bool:
    """Whether ``v`` is a list of ``n`` floats, each within [lo, hi] (so the checked path
    would accept it unchanged)."""
    if type(v) is not list or len(v) != n:
        return False
    for x in v:  # noqa: SIM110 (a plain loop: faster than all() over a generator)
        if type(x) is not float or not lo <= x <= hi:
            return False
    return True


def _nums(v: Any, name: str, n: int, rng: tuple[float, float]) -> tuple[float, ...]:
    if _floats_within(v, n, rng[0], rng[1]):
        return tuple(v)
    return tuple(_num(x, f"{name}[{i}]", *rng) for i, x in enumerate(_list(v, name, n)))


def _header(w: list[Any]) -> Header:
    version = w[1]
    if isinstance(version, bool) or not isinstance(version, int):
        raise DecodeError("bad_type", "version must be an integer")
    if version != SCHEMA_VERSION:
        raise DecodeError("bad_version", f"schema version {version}, expected {SCHEMA_VERSION}")
    seq = w[2]
    if isinstance(seq, bool) or not isinstance(seq, int):
        raise DecodeError("bad_type", "seq must be an integer")
    if not 0 <= seq <= SEQ_MAX:
        raise DecodeError("out_of_range", f"seq={seq}")
    return Header(seq=seq, t_s=_num(w[3], "t_s", *TIME_RANGE_S),
                  energy_total_j=_num(w[4], "energy_total_j", *ENERGY_RANGE_J),
                  version=version)


def _finger(v: Any, name: str) -> FingerState:
    if (type(v) is list and len(v) == _FINGER_FIELDS
            and _floats_within(v[:3], 3, *FINGER_ANGLE_RANGE_RAD)
            and type(v[3]) is float and LOAD_RANGE_UNITS[0] <= v[3] <= LOAD_RANGE_UNITS[1]
            and _floats_within(v[4], N_PRESSURE, *PRESSURE_RANGE)
            and type(v[5]) is list and len(v[5]) == N_PRESSURE
            and all(type(c) is bool for c in v[5])):  # valid: the checked path's result
        return FingerState(v[0], v[1], v[2], v[3], tuple(v[4]), tuple(v[5]))
    f = _list(v, name, _FINGER_FIELDS)
    contact = _list(f[5], f"{name}.contact", N_PRESSURE)
    if not all(isinstance(c, bool) for c in contact):
        raise DecodeError("bad_type", f"{name}.contact must be booleans")
    return FingerState(
        proximal_rad=_num(f[0], f"{name}.proximal_rad", *FINGER_ANGLE_RANGE_RAD),
        distal_rad=_num(f[1], f"{name}.distal_rad", *FINGER_ANGLE_RANGE_RAD),
        motor_angle_rad=_num(f[2], f"{name}.motor_angle_rad", *FINGER_ANGLE_RANGE_RAD),
        load_units=_num(f[3], f"{name}.load_units", *LOAD_RANGE_UNITS),
        pressure=_nums(f[4], f"{name}.pressure", N_PRESSURE, PRESSURE_RANGE),
        contact=tuple(contact),
    )


def _body(cls: type, h: Header, b: list[Any]) -> Message:
    if cls is MasterState:
        return MasterState(h, _num(b[0], "grip_position_m", *GRIP_POSITION_RANGE_M),
                           _num(b[1], "grip_velocity_m_s", *GRIP_VELOCITY_RANGE_M_S),
                           _num(b[2], "echo_t_s", *ECHO_RANGE_S),
                           _num(b[3], "echo_held_s", *HELD_RANGE_S))
    if cls is ForceCommand:
        return ForceCommand(h, _num(b[0], "force_n", *FORCE_RANGE_N),
                            _model(b[1], "model", MODEL_STIFFNESS_RANGE))
    if cls is HandCommand:
        mode = b[2]
        if isinstance(mode, bool) or not isinstance(mode, int):
            raise DecodeError("bad_type", "mode must be an integer")
        if mode not in HandMode._value2member_map_:
            raise DecodeError("out_of_range", f"mode={mode}")
        sp = _nums(b[0], "finger_setpoint_rad", N_FINGERS, FINGER_ANGLE_RANGE_RAD)
        fu = _nums(b[3], "finger_force_units", N_FINGERS, FORCE_UNITS_RANGE)
        return HandCommand(h, sp, _num(b[1], "preshape_rad", *PRESHAPE_RANGE_RAD),  # type: ignore[arg-type]
                           HandMode(mode), fu,  # type: ignore[arg-type]
                           _num(b[4], "hand_echo_t_s", *ECHO_RANGE_S))
    fingers = _list(b[0], "fingers", N_FINGERS)
    return HandState(h, tuple(_finger(f, f"fingers[{i}]") for i, f in enumerate(fingers)),  # type: ignore[arg-type]
                     _num(b[1], "preshape_rad", *PRESHAPE_RANGE_RAD),
                     _num(b[2], "echo_t_s", *ECHO_RANGE_S),
                     _num(b[3], "echo_held_s", *HELD_RANGE_S),
                     _model(b[4], "contact_model", CONTACT_STIFFNESS_RANGE),
                     _count(b[5], "servo_fault_trips"), _flag(b[6], "servo_safe"))


def _count(v: Any, name: str) -> int:
    if isinstance(v, bool) or not isinstance(v, int):
        raise DecodeError("bad_type", f"{name} must be an integer")
    if not 0 <= v <= SEQ_MAX:
        raise DecodeError("out_of_range", f"{name}={v}")
    return v


def _flag(v: Any, name: str) -> bool:
    if not isinstance(v, bool):
        raise DecodeError("bad_type", f"{name} must be a boolean")
    return v


def _model(v: Any, name: str, stiffness: tuple[float, float]) -> tuple[float, ...]:
    """``(contact_rad, stiffness)`` per finger, flattened; stiffness never negative."""
    lo_a, hi_a = FINGER_ANGLE_RANGE_RAD
    lo_k, hi_k = stiffness
    if (type(v) is list and len(v) == 2 * N_FINGERS
            and all(type(x) is float for x in v)
            and lo_a <= v[0] <= hi_a and lo_a <= v[2] <= hi_a and lo_a <= v[4] <= hi_a
            and lo_k <= v[1] <= hi_k and lo_k <= v[3] <= hi_k and lo_k <= v[5] <= hi_k):
        return tuple(v)
    vals = _list(v, name, 2 * N_FINGERS)
    return tuple(_num(x, f"{name}[{i}]", *(FINGER_ANGLE_RANGE_RAD if i % 2 == 0 else stiffness))
                 for i, x in enumerate(vals))


def _unpack(data: Any) -> Any:
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise DecodeError("not_bytes", f"got {type(data).__name__}")
    if len(data) > MAX_MESSAGE_BYTES:
        raise DecodeError("too_large", f"{len(data)} bytes > {MAX_MESSAGE_BYTES}")
    try:
        return msgpack.unpackb(data, raw=False, use_list=True, strict_map_key=True,
                               max_str_len=MAX_MESSAGE_BYTES, max_bin_len=MAX_MESSAGE_BYTES,
                               max_array_len=64, max_map_len=64, max_ext_len=0)
    except Exception as exc:  # msgpack raises many types (ValueError, TypeError, ...)
        raise DecodeError("malformed", f"{type(exc).__name__}") from None


def decode(data: bytes, expected: type | None = None) -> Message:
    """Decode and validate one message; :class:`DecodeError` (with a reason tag) if bad.

    ``expected``: the message type the caller wants; anything else is ``unexpected_kind``.
    """
    w = _unpack(data)
    if not isinstance(w, list) or len(w) < _HEAD:
        raise DecodeError("bad_shape", "not an array of at least 5 items")
    kind = w[0]
    cls = _TYPE_OF_KIND.get(kind) if isinstance(kind, int) and not isinstance(kind, bool) \
        else None
    if cls is None:
        raise DecodeError("unknown_kind", f"kind={kind!r}")
    if expected is not None and cls is not expected:
        raise DecodeError("unexpected_kind", f"{cls.__name__}, expected {expected.__name__}")
    if len(w) != _HEAD + _N_FIELDS[cls]:
        raise DecodeError("bad_shape", f"{cls.__name__} has {len(w)} items")
    return _body(cls, _header(w), w[_HEAD:])
