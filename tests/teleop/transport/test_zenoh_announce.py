"""A bus opened with ``announce=False`` is invisible to its peers until it announces."""

from __future__ import annotations

import socket
import time

import pytest

from teleop.transport.zenoh_bus import ZenohBus

pytestmark = pytest.mark.network


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_the_token_appears_only_when_announced() -> None:
    ep = f"tcp/127.0.0.1:{_port()}"
    ctl = ZenohBus("controller", session="announce", listen=[ep], connect=[])
    hand = ZenohBus("hand", session="announce", listen=[], connect=[ep], announce=False)
    try:
        deadline = time.monotonic() + 10.0
        while not hand.alive("controller") and time.monotonic() < deadline:
            time.sleep(0.01)
        assert hand.alive("controller")  # the hand sees its peers before announcing
        time.sleep(0.3)
        assert not ctl.alive("hand")
        hand.announce()
        hand.announce()  # once only
        deadline = time.monotonic() + 10.0
        while not ctl.alive("hand") and time.monotonic() < deadline:
            time.sleep(0.01)
        assert ctl.alive("hand")
    finally:
        hand.close()
        ctl.close()
