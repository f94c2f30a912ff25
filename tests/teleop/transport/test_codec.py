"""Codec: exact round trips for every message, typed errors for everything else."""

from __future__ import annotations

import logging
import math

import msgpack
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from teleop.errors import DecodeError
from teleop.messages import (
    SCHEMA_VERSION,
    FingerState,
    ForceCommand,
    HandCommand,
    HandMode,
    HandState,
    Header,
    MasterState,
)
from teleop.transport import codec
from teleop.transport.codec import MAX_MESSAGE_BYTES, REASONS, decode, encode
from teleop.transport.safe_decoder import SafeDecoder


def _f(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False)


headers = st.builds(Header, seq=st.integers(0, 2**63 - 1), t_s=_f(*codec.TIME_RANGE_S),
                    energy_total_j=_f(*codec.ENERGY_RANGE_J))
angles = _f(*codec.FINGER_ANGLE_RANGE_RAD)
fingers = st.builds(
    FingerState, proximal_rad=angles, distal_rad=angles, motor_angle_rad=angles,
    load_units=_f(*codec.LOAD_RANGE_UNITS),
    pressure=st.tuples(*[_f(*codec.PRESSURE_RANGE)] * 9),
    contact=st.tuples(*[st.booleans()] * 9),
)
messages = st.one_of(
    st.builds(MasterState, headers, _f(*codec.GRIP_POSITION_RANGE_M),
              _f(*codec.GRIP_VELOCITY_RANGE_M_S)),
    st.builds(ForceCommand, headers, _f(*codec.FORCE_RANGE_N)),
    st.builds(HandCommand, headers, st.tuples(angles, angles, angles),
              _f(*codec.PRESHAPE_RANGE_RAD), st.sampled_from(list(HandMode)),
              st.tuples(*[_f(*codec.FORCE_UNITS_RANGE)] * 3)),
    st.builds(HandState, headers, st.tuples(fingers, fingers, fingers),
              _f(*codec.PRESHAPE_RANGE_RAD), servo_fault_trips=st.integers(0, 2**63 - 1),
              servo_safe=st.booleans()),
)


@given(messages)
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_round_trip_is_exact(msg: object) -> None:
    data = encode(msg)  # type: ignore[arg-type]
    assert len(data) <= MAX_MESSAGE_BYTES
    out = decode(data, type(msg))
    assert out == msg
    assert type(out) is type(msg)
    if isinstance(out, HandCommand):
        assert isinstance(out.mode, HandMode)


@given(st.binary(max_size=3000))
@settings(max_examples=500, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_arbitrary_bytes_give_typed_error(data: bytes) -> None:
    try:
        decode(data)
    except DecodeError as exc:
        assert exc.reason in REASONS


msgpack_values = st.recursive(
    st.none() | st.booleans() | st.integers(-(2**63), 2**64 - 1) | st.floats()
    | st.text(max_size=10) | st.binary(max_size=10),
    lambda inner: st.lists(inner, max_size=8)
    | st.dictionaries(st.text(max_size=5), inner, max_size=4),
    max_leaves=40,
)


@given(msgpack_values)
@settings(max_examples=500, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_arbitrary_msgpack_structures_give_typed_error(value: object) -> None:
    try:
        decode(msgpack.packb(value, use_bin_type=True))
    except DecodeError as exc:
        assert exc.reason in REASONS


@given(messages, st.data())
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_mutated_valid_messages_never_crash(msg: object, data: st.DataObject) -> None:
    """Replace one field of a valid wire array with anything: a message or a typed error."""
    wire = msgpack.unpackb(encode(msg), raw=False)  # type: ignore[arg-type]
    i = data.draw(st.integers(0, len(wire) - 1))
    wire[i] = data.draw(msgpack_values)
    try:
        decode(msgpack.packb(wire, use_bin_type=True))
    except DecodeError as exc:
        assert exc.reason in REASONS


def _ms(**kw: float) -> bytes:
    h = Header(seq=int(kw.pop("seq", 1)), t_s=kw.pop("t_s", 1.0),
               energy_total_j=kw.pop("energy", 0.5))
    return encode(MasterState(h, kw.get("pos", 0.01), kw.get("vel", 0.0), kw.get("echo", -1.0),
                              kw.get("held", 0.0)))


@pytest.mark.parametrize(("data", "reason"), [
    (_ms(pos=0.051), "out_of_range"),
    (_ms(pos=-0.0101), "out_of_range"),
    (_ms(pos=math.nan), "not_finite"),
    (_ms(vel=math.inf), "not_finite"),
    (_ms(energy=-1e-9), "out_of_range"),
    (_ms(energy=math.inf), "not_finite"),
    (_ms(seq=-1), "out_of_range"),
    (_ms(echo=-1.5), "out_of_range"),
    (_ms(echo=math.nan), "not_finite"),
    (_ms(held=-0.001), "out_of_range"),
    (b"\x00" * (MAX_MESSAGE_BYTES + 1), "too_large"),
    (b"\xc1", "malformed"),
    (b"\x92\x01", "malformed"),  # truncated array
    (_ms() + b"\x00", "malformed"),  # trailing bytes
    (msgpack.packb({"a": 1}), "bad_shape"),
    (msgpack.packb([99, 1, 0, 0.0, 0.0, 1.0]), "unknown_kind"),
    (msgpack.packb([1, SCHEMA_VERSION + 1, 0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0]), "bad_version"),
    (msgpack.packb([1, SCHEMA_VERSION, 0, 0.0, 0.0, "0.01", 0.0, -1.0, 0.0]), "bad_type"),
    (msgpack.packb([1, SCHEMA_VERSION, 0, 0.0, 0.0, True, 0.0, -1.0, 0.0]), "bad_type"),
    (msgpack.packb([1, SCHEMA_VERSION, 0, 0.0, 0.0, 0.0, 0.0]), "bad_shape"),
    (msgpack.packb([3, SCHEMA_VERSION, 0, 0.0, 0.0, [0.0, 0.0], 0.0, 0, [0.0] * 3, -1.0]),
     "bad_shape"),
    (msgpack.packb([3, SCHEMA_VERSION, 0, 0.0, 0.0, [0.0] * 3, 0.0, 0, [0.0] * 3]), "bad_shape"),
    (msgpack.packb([3, SCHEMA_VERSION, 0, 0.0, 0.0, [0.0] * 3, 0.0, 7, [0.0] * 3, -1.0]),
     "out_of_range"),
    (msgpack.packb([3, SCHEMA_VERSION, 0, 0.0, 0.0, [9.0, 0.0, 0.0], 0.0, 0, [0.0] * 3, -1.0]),
     "out_of_range"),
    (msgpack.packb([3, SCHEMA_VERSION, 0, 0.0, 0.0, [0.0] * 3, 0.0, 0, [0.0] * 3, -2.0]),
     "out_of_range"),
    (msgpack.packb([3, SCHEMA_VERSION, 0, 0.0, 0.0, [0.0] * 3, 0.0, 0, [0.0] * 3, math.nan]),
     "not_finite"),
])
def test_bad_messages_have_stable_reasons(data: bytes, reason: str) -> None:
    with pytest.raises(DecodeError) as info:
        decode(data)
    assert info.value.reason == reason


def test_hand_state_needs_9_pressures_and_boolean_contacts() -> None:
    fs = FingerState(0.1, 0.2, 0.3, 10.0, (0.0,) * 9, (False,) * 9)
    good = HandState(Header(0, 0.0, 0.0), (fs, fs, fs), 0.0)
    wire = msgpack.unpackb(encode(good), raw=False)
    wire[5][1][4] = [0.0] * 8
    with pytest.raises(DecodeError, match="bad_shape"):
        decode(msgpack.packb(wire))
    wire = msgpack.unpackb(encode(good), raw=False)
    wire[5][2][5] = [0] * 9
    with pytest.raises(DecodeError, match="bad_type"):
        decode(msgpack.packb(wire))
    wire = msgpack.unpackb(encode(good), raw=False)
    wire[5] = wire[5][:2]
    with pytest.raises(DecodeError, match="bad_shape"):
        decode(msgpack.packb(wire))


def test_expected_type_is_enforced() -> None:
    with pytest.raises(DecodeError) as info:
        decode(_ms(), ForceCommand)
    assert info.value.reason == "unexpected_kind"
    assert isinstance(decode(_ms(), MasterState), MasterState)


def test_not_bytes() -> None:
    with pytest.raises(DecodeError, match="not_bytes"):
        decode("hello")  # type: ignore[arg-type]


def test_safe_decoder_counts_and_rate_limits_logs(caplog: pytest.LogCaptureFixture) -> None:
    dec = SafeDecoder("test", log_interval_s=60.0)
    with caplog.at_level(logging.WARNING, logger="teleop.transport"):
        assert dec.decode(_ms(), MasterState) is not None
        for _ in range(50):
            assert dec.decode(b"\xc1") is None
        assert dec.decode(_ms(pos=1.0)) is None
        dec.reject("stale_seq", "seq 3 <= 4")
    snap = dec.counts()
    assert snap.accepted == 1
    assert snap.rejected == 52
    assert snap.count("malformed") == 50
    assert snap.count("out_of_range") == 1
    assert snap.count("stale_seq") == 1
    assert snap.count("too_large") == 0
    lines = [r.getMessage() for r in caplog.records]
    assert sum("malformed" in s for s in lines) == 1  # rate limited
    assert any("out_of_range" in s and "grip_position_m" in s for s in lines)
    with pytest.raises(AttributeError):
        snap.accepted = 5  # type: ignore[misc]
    assert dec.counts().count("malformed") == 50 and snap.rejected == 52


@given(st.lists(st.one_of(st.binary(max_size=600), messages.map(encode),
                          msgpack_values.map(lambda v: msgpack.packb(v, use_bin_type=True))),
                max_size=20))
@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_safe_decoder_never_raises_and_counts_everything(inputs: list[bytes]) -> None:
    dec = SafeDecoder("fuzz", log_interval_s=1e9)
    logging.getLogger("teleop.transport").disabled = True
    try:
        results = [dec.decode(b) for b in inputs]
    finally:
        logging.getLogger("teleop.transport").disabled = False
    snap = dec.counts()
    assert snap.accepted == sum(r is not None for r in results)
    assert snap.accepted + snap.rejected == len(inputs)
    assert {reason for reason, _ in snap.by_reason} <= set(REASONS)


def test_echo_timestamp_round_trips() -> None:
    """Schema 2: MasterState and HandState echo the peer's latest command timestamp."""
    ms = MasterState(Header(3, 2.0, 0.1), 0.01, 0.0, echo_t_s=1.75, echo_held_s=0.002)
    assert decode(encode(ms)) == ms
    fs = FingerState(0.1, 0.2, 0.3, 10.0, (0.0,) * 9, (False,) * 9)
    hs = HandState(Header(0, 0.0, 0.0), (fs, fs, fs), 0.0, echo_t_s=12.5, echo_held_s=0.02)
    assert decode(encode(hs)) == hs
    assert MasterState(Header(0, 0.0, 0.0), 0.0, 0.0).echo_t_s < 0  # none received yet


def test_hand_state_carries_the_servo_fault_count_and_rejects_bad_ones() -> None:
    """Schema 4: the hand's servo-error safe-state episodes and whether it is held now."""
    fs = FingerState(0.1, 0.2, 0.3, 10.0, (0.0,) * 9, (False,) * 9)
    hs = HandState(Header(0, 0.0, 0.0), (fs, fs, fs), 0.0, servo_fault_trips=3,
                   servo_safe=True)
    back = decode(encode(hs))
    assert isinstance(back, HandState) and back.servo_fault_trips == 3 and back.servo_safe
    for i, bad, reason in [(10, -1, "out_of_range"), (10, 1.0, "bad_type"),
                           (10, True, "bad_type"), (11, 1, "bad_type")]:
        wire = msgpack.unpackb(encode(hs), raw=False)
        wire[i] = bad
        with pytest.raises(DecodeError) as info:
            decode(msgpack.packb(wire))
        assert info.value.reason == reason, (i, bad)
