"""Every flood payload is invalid for the reason it is named for, on every signal, at the
present schema (the hand-state and force-command payloads once had too few fields, so every
one of them was rejected as ``bad_shape`` whatever it was meant to test)."""

from __future__ import annotations

import pytest

from teleop.analysis.faults import FLOOD_KINDS, malformed_payload
from teleop.messages import ForceCommand, HandCommand, HandState, MasterState
from teleop.transport.codec import DecodeError, decode

TYPES = {"master_state": MasterState, "force_command": ForceCommand,
         "hand_command": HandCommand, "hand_state": HandState}
BUS_LEVEL = {"stale_seq", "energy_jump"}  # well-formed: the receiving bus rejects them


@pytest.mark.parametrize("signal", sorted(TYPES))
def test_each_payload_fails_for_its_named_reason(signal: str) -> None:
    for i, (kind, reason) in enumerate(FLOOD_KINDS):
        got_kind, data = malformed_payload(i, signal)
        assert got_kind == kind
        if reason in BUS_LEVEL:
            msg = decode(data, TYPES[signal])  # decodes; the sequence/energy filter stops it
            assert isinstance(msg, TYPES[signal])
            continue
        with pytest.raises(DecodeError) as info:
            decode(data, TYPES[signal])
        if reason != "*":
            assert info.value.reason == reason, (signal, kind, info.value.reason)
