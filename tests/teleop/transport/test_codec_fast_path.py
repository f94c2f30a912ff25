"""The codec accepts valid numbers at once and sends everything else down the checked path:
one bad number anywhere in a list (set-points, pressures, a contact model, a finger's angles)
still gives the checked path's reason, and an int or bool where a float belongs is typed."""

from __future__ import annotations

import math
from dataclasses import replace

import msgpack
import pytest

from teleop.errors import DecodeError
from teleop.messages import FingerState, ForceCommand, HandCommand, HandState, Header
from teleop.transport.codec import decode, encode

H = Header(seq=1, t_s=0.5, energy_total_j=0.1)
FINGER = FingerState(0.3, 0.1, 0.4, 10.0, (1.0,) * 9, (False,) * 9)


def _hand_state(**finger: object) -> HandState:
    f = replace(FINGER, **finger)  # type: ignore[arg-type]
    return HandState(H, (FINGER, f, FINGER), 0.2)


def _reason(msg: object) -> str:
    with pytest.raises(DecodeError) as exc:
        decode(encode(msg))  # type: ignore[arg-type]
    return exc.value.reason


@pytest.mark.parametrize("bad", [1e9, -1e9, math.inf, math.nan])
def test_one_bad_number_in_any_list_is_caught(bad: float) -> None:
    want = "not_finite" if not math.isfinite(bad) else "out_of_range"
    assert _reason(HandCommand(H, (0.1, bad, 0.2), 0.0)) == want
    for i in range(6):  # every angle and every stiffness of the model
        model = tuple(bad if j == i else (0.1, 5.0)[j % 2] for j in range(6))
        assert _reason(ForceCommand(H, 1.0, model)) == want
    assert _reason(_hand_state(pressure=(1.0,) * 8 + (bad,))) == want
    assert _reason(_hand_state(distal_rad=bad)) == want
    assert _reason(_hand_state(load_units=bad)) == want
    assert _reason(HandState(H, (FINGER,) * 3, 0.2, contact_model=(0.1, bad, 0.1, 1.0, 0.1,
                                                                      1.0))) == want


def test_negative_stiffness_and_wrong_types_are_caught() -> None:
    assert _reason(ForceCommand(H, 1.0, (0.1, -1.0, 0.1, 5.0, 0.1, 5.0))) == "out_of_range"
    wire = msgpack.unpackb(encode(HandCommand(H, (0.1, 0.2, 0.3), 0.0)))
    for bad in (True, "x", None):
        w = list(wire)
        w[5] = [0.1, bad, 0.3]
        with pytest.raises(DecodeError) as exc:
            decode(msgpack.packb(w))
        assert exc.value.reason == "bad_type"
    w = list(wire)
    w[5] = [0.1, 1, 0.3]  # an int is a number: accepted, as a float
    assert decode(msgpack.packb(w)).finger_setpoint_rad == (0.1, 1.0, 0.3)  # type: ignore[union-attr]
    fw = msgpack.unpackb(encode(_hand_state()))
    fw[5][1][5] = [False] * 8 + [1]
    with pytest.raises(DecodeError) as exc:
        decode(msgpack.packb(fw))
    assert exc.value.reason == "bad_type"


def test_valid_messages_decode_to_equal_messages() -> None:
    for msg in (HandCommand(H, (0.1, 0.2, 0.3), 0.1), _hand_state(),
                ForceCommand(H, 2.0, (0.1, 5.0, 0.2, 0.0, 0.3, 1e4))):
        assert decode(encode(msg)) == msg
