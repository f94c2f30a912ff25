"""A read-only dashboard session (``teleop watch``): the ``observer`` role.

Opens a zenoh **client** session to ``zenoh.endpoint`` (the controller relays the whole
session to its clients), in secure mode with the observer's own certificate, key and password
(``secure_zenoh_config(cfg, "observer")``: every service refuses whatever an observer would
publish).  It declares no publisher and no liveliness token: it only subscribes to the data
keys of the four signals, decodes every sample with the services' validating decoder, counts
what arrived and what was rejected (per reason), and logs the signals to a rerun dashboard at
``dashboard.rate_hz`` per signal under ``observer/...``.
"""

from __future__ import annotations

import json
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from teleop.config import TeleopConfig
from teleop.errors import UserInputError
from teleop.messages import ForceCommand, HandCommand, HandState, MasterState, Message
from teleop.transport.keys import SIGNALS, data_key
from teleop.transport.safe_decoder import SafeDecoder

TYPES: dict[str, type] = {"master_state": MasterState, "force_command": ForceCommand,
                          "hand_command": HandCommand, "hand_state": HandState}


@dataclass
class ObserverCounts:
    """What the observer saw (the zenoh callback threads update it under ``lock``)."""

    received: dict[str, int] = field(default_factory=lambda: dict.fromkeys(SIGNALS, 0))
    latest: dict[str, Message] = field(default_factory=dict)
    lock: threading.Lock = field(default_factory=threading.Lock)


def observer_zenoh_config(cfg: TeleopConfig) -> Any:
    """The observer's zenoh config: a client of ``zenoh.endpoint``, secure keys if enabled."""
    import zenoh

    from teleop.security.zenoh_secure import secure_zenoh_config

    conf = zenoh.Config()
    conf.insert_json5("mode", json.dumps("client"))
    conf.insert_json5("connect/endpoints", json.dumps([cfg.zenoh.endpoint]))
    conf.insert_json5("scouting/multicast/enabled", json.dumps(False))
    for key, value in secure_zenoh_config(cfg, "observer").items():
        conf.insert_json5(key, value)
    return conf


def log_message(rec: Any, t_s: float, signal: str, msg: Message) -> None:
    """One message on the dashboard (``observer/<signal>/...`` scalars)."""
    import rerun as rr

    from teleop.viz.dashboard import set_time

    set_time(rec, t_s)

    def scalar(path: str, value: float) -> None:
        rec.log(f"observer/{signal}/{path}", rr.Scalars(float(value)))

    if isinstance(msg, MasterState):
        scalar("grip_position_m", msg.grip_position_m)
    elif isinstance(msg, ForceCommand):
        scalar("force_n", msg.force_n)
    elif isinstance(msg, HandCommand):
        for i, sp in enumerate(msg.finger_setpoint_rad):
            scalar(f"finger{i + 1}/setpoint_rad", sp)
    elif isinstance(msg, HandState):
        for i, f in enumerate(msg.fingers):
            scalar(f"finger{i + 1}/proximal_rad", f.proximal_rad)
            scalar(f"finger{i + 1}/max_pressure", max(f.pressure))
        scalar("servo_fault_trips", msg.servo_fault_trips)
    scalar("energy_total_j", msg.header.energy_total_j)


def watch(cfg: TeleopConfig, duration_s: float | None, rec: Any | None,
          progress: Callable[[str], None], stop: threading.Event | None = None
          ) -> dict[str, Any]:
    """Observe the session until ``duration_s`` (or ``stop``); the counts as a JSON dict."""
    import zenoh

    stop = stop or threading.Event()
    decoder = SafeDecoder("observer")
    counts = ObserverCounts()
    epoch = time.monotonic()
    period = 1.0 / cfg.dashboard.rate_hz
    next_log = dict.fromkeys(SIGNALS, 0.0)

    def on_sample(signal: str) -> Callable[[Any], None]:
        expected = TYPES[signal]

        def callback(sample: Any) -> None:
            msg = decoder.decode(sample.payload.to_bytes(), expected)
            if msg is None:
                return
            t = time.monotonic() - epoch
            with counts.lock:
                counts.received[signal] += 1
                counts.latest[signal] = msg
                due = rec is not None and t >= next_log[signal]
                if due:
                    next_log[signal] = t + period
            if due:
                log_message(rec, t, signal, msg)

        return callback

    try:
        session = zenoh.open(observer_zenoh_config(cfg))
    except zenoh.ZError as exc:
        why = str(exc).split(" at /", 1)[0].strip()
        raise UserInputError(f"zenoh.endpoint {cfg.zenoh.endpoint}: cannot open the observer "
                             f"session ({why})") from None
    try:
        subs = [session.declare_subscriber(data_key(cfg.session.name, s), on_sample(s))
                for s in SIGNALS]
        progress(f"observing session {cfg.session.name!r} at {cfg.zenoh.endpoint} as "
                 f"'observer' ({'secure' if cfg.security.enabled else 'plain'})")
        end = math.inf if duration_s is None else time.monotonic() + duration_s
        next_report = time.monotonic() + 5.0
        try:
            while not stop.is_set() and time.monotonic() < end:
                stop.wait(min(0.1, max(0.0, end - time.monotonic())))
                if time.monotonic() >= next_report:
                    with counts.lock:
                        total = sum(counts.received.values())
                    progress(f"{time.monotonic() - epoch:.0f} s: {total} messages")
                    next_report += 5.0
        except KeyboardInterrupt:
            progress("interrupted")
        for sub in subs:
            sub.undeclare()
    finally:
        session.close()
    snap = decoder.counts()
    with counts.lock:
        return {"session": cfg.session.name, "endpoint": cfg.zenoh.endpoint,
                "secure": cfg.security.enabled, "observed_s": time.monotonic() - epoch,
                "received": dict(counts.received), "rejected": snap.rejected,
                "rejects_by_reason": dict(snap.by_reason)}
