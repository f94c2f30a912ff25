"""Transport: message codec, seeded delay lines, and the bus (in-process or zenoh).

Services code against :class:`Bus`::

    from teleop.transport import InProcessHub, VirtualClock, ZenohBus

    bus = ZenohBus.from_config("controller", cfg)          # live, one process per service
    # lockstep: hub = InProcessHub.from_config(cfg, VirtualClock()); bus = hub.bus("controller")
    bus.publish("hand_command", HandCommand(...))
    for r in bus.receive("master_state"):   # r.message, r.delay_s, r.sent_t_s, r.received_t_s
        ...
    bus.alive("hand"); bus.stats(); bus.close()

:class:`ZenohBus` is imported lazily (it imports zenoh).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from teleop.transport.bus import Bus, BusStats, LinkStats, Received, link_params
from teleop.transport.clock import Clock, MonotonicClock, VirtualClock, wait_until
from teleop.transport.codec import MAX_MESSAGE_BYTES, REASONS, decode, encode
from teleop.transport.delay_line import (
    DelayLineState,
    DelayParams,
    Delivered,
    delay_line_pop_due,
    delay_line_push,
    delay_params,
    next_release_s,
)
from teleop.transport.inproc_bus import InProcessBus, InProcessHub
from teleop.transport.keys import ROLES, SIGNALS, SignalSpec, data_key, liveliness_key
from teleop.transport.safe_decoder import RejectCounts, SafeDecoder

if TYPE_CHECKING:
    from teleop.transport.zenoh_bus import ZenohBus

__all__ = [
    "Bus", "BusStats", "LinkStats", "Received", "link_params",
    "Clock", "MonotonicClock", "VirtualClock", "wait_until",
    "MAX_MESSAGE_BYTES", "REASONS", "decode", "encode",
    "DelayLineState", "DelayParams", "Delivered", "delay_line_pop_due", "delay_line_push",
    "delay_params", "next_release_s",
    "InProcessBus", "InProcessHub",
    "ROLES", "SIGNALS", "SignalSpec", "data_key", "liveliness_key",
    "RejectCounts", "SafeDecoder",
    "ZenohBus",
]


def __getattr__(name: str) -> Any:
    if name == "ZenohBus":
        from teleop.transport.zenoh_bus import ZenohBus

        return ZenohBus
    raise AttributeError(f"module 'teleop.transport' has no attribute {name!r}")
