"""Which messages the codec round-trips exactly: the in-process bus may pass those as objects.

:func:`round_trips` is True only when ``decode(encode(msg), type(msg))`` is certain to
return a message equal to ``msg`` field by field *with the same Python types*, so a receiver
handed ``msg`` itself cannot tell it from the decoded copy.  The argument, against
:mod:`teleop.transport.codec`:

* messages are frozen dataclasses of floats, ints, bools, a :class:`HandMode` and tuples of
  them, so the object cannot change after the check (a list where a tuple belongs fails it);
* every float field must be exactly a ``float`` (not a subclass such as ``numpy.float64``, not
  an ``int`` or ``bool``) within the codec's range for that field: encode writes it as a
  float64, msgpack gives back the same bits, and decode's range check passes (NaN fails every
  range test here as there);
* ``seq``, ``version`` and ``servo_fault_trips`` must be exactly ``int`` (a ``bool`` would come
  back as an ``int``) in range, ``version`` the current schema; flags exactly ``bool``;
  ``mode`` exactly a :class:`HandMode` (encoded as its int, decoded back to the member);
* every tuple has the length decode demands; the encoded size of such a message is fixed by
  its shape (9 bytes per float64, at most 9 per int), far under ``MAX_MESSAGE_BYTES``.

Anything else (a raw payload, a malformed or out-of-range message) is not "exact" and goes
through the checked codec path, which rejects it with its reason as before.
``tests/teleop/transport/test_exact.py`` holds the predicate to the codec itself: every
message it accepts decodes to an equal, same-typed copy, and every mutation of a field the
argument rests on makes it refuse.
"""

from __future__ import annotations

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
from teleop.transport.codec import (
    CONTACT_STIFFNESS_RANGE,
    ECHO_RANGE_S,
    ENERGY_RANGE_J,
    FINGER_ANGLE_RANGE_RAD,
    FORCE_RANGE_N,
    FORCE_UNITS_RANGE,
    GRIP_POSITION_RANGE_M,
    GRIP_VELOCITY_RANGE_M_S,
    HELD_RANGE_S,
    LOAD_RANGE_UNITS,
    MODEL_STIFFNESS_RANGE,
    PRESHAPE_RANGE_RAD,
    PRESSURE_RANGE,
    SEQ_MAX,
    TIME_RANGE_S,
)


def _f(x: object, rng: tuple[float, float]) -> bool:
    return type(x) is float and rng[0] <= x <= rng[1]  # type: ignore[operator]


def _fs(v: object, n: int, rng: tuple[float, float]) -> bool:
    if type(v) is not tuple or len(v) != n:
        return False
    lo, hi = rng
    for x in v:  # noqa: SIM110 (a plain loop: faster than all() over a generator)
        if type(x) is not float or not lo <= x <= hi:
            return False
    return True


def _int(x: object) -> bool:
    return type(x) is int and 0 <= x <= SEQ_MAX


_T_LO, _T_HI = TIME_RANGE_S
_E_LO, _E_HI = ENERGY_RANGE_J
_Q_LO, _Q_HI = GRIP_POSITION_RANGE_M
_V_LO, _V_HI = GRIP_VELOCITY_RANGE_M_S
_ECHO_LO, _ECHO_HI = ECHO_RANGE_S
_HELD_LO, _HELD_HI = HELD_RANGE_S
_F_LO, _F_HI = FORCE_RANGE_N


def _header(h: object) -> bool:
    if type(h) is not Header:
        return False
    seq, t, e = h.seq, h.t_s, h.energy_total_j
    return (type(h.version) is int and h.version == SCHEMA_VERSION
            and type(seq) is int and 0 <= seq <= SEQ_MAX
            and type(t) is float and _T_LO <= t <= _T_HI
            and type(e) is float and _E_LO <= e <= _E_HI)


#: (model, stiffness range, verdict) of the last :func:`_model` check of a tuple: the
#: controller forwards the same model tuple at every tick between two hand states, and a
#: tuple (of floats, or it fails) cannot change, so its verdict is reused by identity
_last_model: tuple[object, object, bool] = (None, None, False)


def _model(v: object, stiffness: tuple[float, float]) -> bool:
    global _last_model
    if type(v) is not tuple or len(v) != 2 * N_FINGERS:
        return False
    last = _last_model
    if v is last[0] and stiffness is last[1]:
        return last[2]
    ok = (_fs(v[0::2], N_FINGERS, FINGER_ANGLE_RANGE_RAD)
          and _fs(v[1::2], N_FINGERS, stiffness))
    _last_model = (v, stiffness, ok)
    return ok


def _finger(f: object) -> bool:
    return (type(f) is FingerState and _f(f.proximal_rad, FINGER_ANGLE_RANGE_RAD)
            and _f(f.distal_rad, FINGER_ANGLE_RANGE_RAD)
            and _f(f.motor_angle_rad, FINGER_ANGLE_RANGE_RAD)
            and _f(f.load_units, LOAD_RANGE_UNITS)
            and _fs(f.pressure, N_PRESSURE, PRESSURE_RANGE)
            and type(f.contact) is tuple and len(f.contact) == N_PRESSURE
            and all(type(c) is bool for c in f.contact))


def round_trips(msg: Message) -> bool:
    """Whether the codec gives ``msg`` back exactly (see the module docstring)."""
    t = type(msg)
    if t is MasterState:  # (the 1 kHz messages' checks written out: :func:`_f` each)
        q, v, e, h = msg.grip_position_m, msg.grip_velocity_m_s, msg.echo_t_s, msg.echo_held_s
        return (_header(msg.header)
                and type(q) is float and _Q_LO <= q <= _Q_HI
                and type(v) is float and _V_LO <= v <= _V_HI
                and type(e) is float and _ECHO_LO <= e <= _ECHO_HI
                and type(h) is float and _HELD_LO <= h <= _HELD_HI)
    if t is ForceCommand:
        f = msg.force_n
        return (_header(msg.header) and type(f) is float and _F_LO <= f <= _F_HI
                and _model(msg.model, MODEL_STIFFNESS_RANGE))
    if t is HandCommand:
        return (_header(msg.header)
                and _fs(msg.finger_setpoint_rad, N_FINGERS, FINGER_ANGLE_RANGE_RAD)
                and _f(msg.preshape_rad, PRESHAPE_RANGE_RAD) and type(msg.mode) is HandMode
                and _fs(msg.finger_force_units, N_FINGERS, FORCE_UNITS_RANGE)
                and _f(msg.hand_echo_t_s, ECHO_RANGE_S))
    if t is HandState:
        fingers = msg.fingers
        return (_header(msg.header) and type(fingers) is tuple and len(fingers) == N_FINGERS
                and all(_finger(f) for f in fingers)
                and _f(msg.preshape_rad, PRESHAPE_RANGE_RAD) and _f(msg.echo_t_s, ECHO_RANGE_S)
                and _f(msg.echo_held_s, HELD_RANGE_S)
                and _model(msg.contact_model, CONTACT_STIFFNESS_RANGE)
                and _int(msg.servo_fault_trips) and type(msg.servo_safe) is bool)
    return False


__all__ = ["round_trips"]
