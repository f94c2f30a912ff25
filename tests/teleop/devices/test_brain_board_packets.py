"""The brain board's packets: layout, round trips, and drops counted by reason."""

from __future__ import annotations

import contextlib
import struct

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from teleop.devices.brain_board_packets import (
    PALM_LEN,
    STATE_LEN,
    BoardState,
    ModesPacket,
    StateReceiver,
    TargetsPacket,
    board_time_advanced,
    decode_command,
    decode_state,
    encode_modes,
    encode_state,
    encode_targets,
)
from teleop.errors import DecodeError


def state(t_us: int = 1000, magic: int = 1) -> BoardState:
    return BoardState(
        header=(magic, 0, 0, 0), systime_us=t_us,
        pressures=tuple(range(100, 138)), temperatures=tuple(range(300, 338)),
        encoders=(10, 16383, 200), dxl_error=(0, 32, 0, 0), dxl_angle=(1, 65535, 3, 4),
        dxl_speed=(0, 1024, 2047, 5), dxl_load=(1023, 1024, 0, 2047), dxl_voltage=(120,) * 4,
        dxl_temperature=(35, 36, 37, 38))


def test_the_state_struct_is_202_bytes_little_endian_in_the_documented_order() -> None:
    s = state(t_us=0x01020304)
    data = encode_state(s)
    assert STATE_LEN == 202 and len(data) == 202
    assert data[:4] == b"\x01\x00\x00\x00"
    assert data[4:8] == bytes((4, 3, 2, 1))  # uint32 little-endian
    assert struct.unpack_from("<H", data, 8)[0] == 100  # first pressure
    assert struct.unpack_from("<H", data, 8 + 76)[0] == 300  # first temperature
    assert struct.unpack_from("<3H", data, 160) == (10, 16383, 200)  # encoders
    assert data[166:170] == bytes((0, 32, 0, 0))  # dxl_error
    assert struct.unpack_from("<4H", data, 170) == (1, 65535, 3, 4)  # angles
    assert data[194:198] == bytes((120,) * 4) and data[198:202] == bytes((35, 36, 37, 38))
    assert decode_state(data) == s
    assert decode_state(data + bytes(PALM_LEN)) == s  # palm data appended: accepted


def test_mode_and_target_packets_match_the_driver() -> None:
    assert encode_modes((2, 2, 1, 0)) == bytes((1, 2, 2, 1, 0))
    assert encode_targets((0x1234, 1, 65535, 0)) == bytes((2, 0x12, 0x34, 0, 1, 255, 255, 0, 0))
    assert decode_command(encode_modes((0, 1, 2, 2))) == ModesPacket((0, 1, 2, 2))
    assert decode_command(encode_targets((5, 6, 7, 8))) == TargetsPacket((5, 6, 7, 8))
    with pytest.raises(ValueError):
        encode_modes((3, 0, 0, 0))
    for bad, reason in ((b"", "bad_length"), (bytes((1, 2, 2)), "bad_length"),
                        (bytes((1, 2, 2, 2, 3)), "bad_mode"), (bytes((2, 1)), "bad_length"),
                        (bytes((9, 0, 0, 0, 0)), "unknown_type"), ("x", "not_bytes")):
        with pytest.raises(DecodeError) as exc:
            decode_command(bad)
        assert exc.value.reason == reason


@pytest.mark.parametrize(("data", "reason"), [
    (encode_state(state())[:-1], "bad_length"),
    (encode_state(state()) + b"\x00", "bad_length"),
    (b"", "bad_length"),
    (encode_state(state(magic=2)), "bad_magic"),
    (12, "not_bytes"),
])
def test_malformed_state_packets_are_dropped_and_counted_by_reason(data: object,
                                                                   reason: str) -> None:
    with pytest.raises(DecodeError) as exc:
        decode_state(data)
    assert exc.value.reason == reason
    rx = StateReceiver()
    assert rx.accept(data) is None
    c = rx.counts()
    assert (c.accepted, c.rejected, c.count(reason)) == (0, 1, 1)


def test_board_time_must_move_forward_across_the_uint32_wrap() -> None:
    assert board_time_advanced(None, 5)
    assert board_time_advanced(10, 11) and not board_time_advanced(11, 11)
    assert not board_time_advanced(11, 10)
    assert board_time_advanced(2**32 - 10, 5)  # wrapped: still forward
    rx = StateReceiver()
    for t, ok in ((1000, True), (26000, True), (26000, False), (1000, False), (51000, True)):
        assert (rx.accept(encode_state(state(t))) is not None) is ok
    c = rx.counts()
    assert (c.accepted, c.count("stale_time")) == (3, 2)


def test_a_restarted_board_is_followed_again_after_a_run_of_advancing_packets() -> None:
    rx = StateReceiver(resync_after=4)
    assert rx.accept(encode_state(state(10_000_000))) is not None
    got = [rx.accept(encode_state(state(25_000 * k))) is not None for k in range(1, 7)]
    assert got == [False, False, False, True, True, True]
    assert rx.resyncs == 1 and rx.counts().count("stale_time") == 3
    # a lone replayed old packet does not resync
    assert rx.accept(encode_state(state(1))) is None and rx.resyncs == 1


FUZZ = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@FUZZ
@given(st.one_of(st.binary(max_size=300),
                 st.binary(min_size=STATE_LEN, max_size=STATE_LEN),
                 st.binary(min_size=STATE_LEN - 1, max_size=STATE_LEN - 1).map(lambda b: b"\x01"
                                                                                + b)))
def test_malformed_bytes_never_raise(data: bytes) -> None:
    rx = StateReceiver()
    out = rx.accept(data)
    c = rx.counts()
    assert c.accepted + c.rejected == 1
    if out is not None:
        assert len(data) == STATE_LEN and data[0] == 1
        assert encode_state(out) == data  # what was accepted is exactly what was sent
    with contextlib.suppress(DecodeError):
        decode_command(data)
