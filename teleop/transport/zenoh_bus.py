"""The bus over zenoh (peer mode): one session per service process.

* Endpoints: by default the controller listens on ``zenoh.endpoint`` and the master and hand
  connect to it (the ``teleop up`` star); ``zenoh.listen``/``zenoh.connect`` add more, and
  explicit ``listen=``/``connect=`` arguments replace both.  Multicast scouting is off
  unless ``zenoh.multicast_scouting``.
* Keys: ``teleop/<session>/<sender role>/<signal>`` (:mod:`teleop.transport.keys`).  Each
  payload carries an attachment: the sender's monotonic send time (float64, seconds).
* Delay lines run at the receiver.  With ``shared_clock`` (all processes on one machine, the
  default) a message's delay counts from the sender's send time, so the configured delay is
  the true one-way delay and the achieved delay measures it; otherwise it counts from the
  arrival time on the receiver's clock (works across machines; the network adds to it).
* Liveliness: a token ``teleop/<session>/<role>/alive`` per service; a subscriber (with
  history) on the others' tokens answers :meth:`ZenohBus.alive`.  A killed peer's token
  disappears as soon as its TCP link drops.  When a peer (re)appears, the sequence filter
  of its signals is reset so a restarted sender is accepted (from its first ``seq``; a
  ``seq`` too far ahead of the last accepted one is otherwise dropped as ``seq_jump``).
* Roster: a queryable ``teleop/<session>/<role>/roster`` answers a starting service with this
  role and the roles whose tokens it sees, so a second service of a running role is refused
  at its start (:mod:`teleop.transport.roster`).
* ``close()`` undeclares subscribers, publishers and the token and closes the session; it
  must be called (zenoh sessions keep the process alive otherwise).
* GIL: zenoh delivers samples through a Python callback, which needs the GIL; a service
  loop that spin-waits holds it for up to the interpreter's switch interval (5 ms by
  default), which delays arrivals in bursts.  The constructor lowers the process's switch
  interval to ``gil_switch_interval_s`` (100 us) unless that is None.
"""

from __future__ import annotations

import collections
import json
import math
import struct
import sys
import threading
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

import zenoh

from teleop.config.schema import TeleopConfig
from teleop.config.transport import LinksConfig, ZenohConfig
from teleop.errors import ConfigError
from teleop.messages import Message
from teleop.transport.bus import (
    BusStats,
    Inbox,
    Received,
    check_publish,
    check_receive,
    make_inboxes,
)
from teleop.transport.clock import Clock, MonotonicClock
from teleop.transport.codec import encode
from teleop.transport.endpoint_check import role_endpoints
from teleop.transport.keys import (
    ROLES,
    SIGNALS,
    check_role,
    check_session,
    data_key,
    liveliness_key,
    liveliness_pattern,
    role_from_key,
    roster_key,
)
from teleop.transport.roster import encode_reply
from teleop.transport.safe_decoder import SafeDecoder

_STAMP = struct.Struct("<d")
TX_QUEUE_BATCHES = 16
#: A send stamp older than this (or in the future, or not finite) is ignored: the delay
#: then counts from the arrival.
MAX_STAMP_AGE_S = 10.0


def _drain(queue: collections.deque[tuple[bytes, float]]) -> Iterator[tuple[bytes, float]]:
    """Pop from the left until empty (safe while a zenoh thread appends on the right)."""
    while queue:
        yield queue.popleft()


def zenoh_config(mode: str, listen: Sequence[str], connect: Sequence[str],
                 multicast_scouting: bool = False) -> zenoh.Config:
    """A zenoh :class:`zenoh.Config` for one service."""
    conf = zenoh.Config()
    conf.insert_json5("mode", json.dumps(mode))
    conf.insert_json5("listen/endpoints", json.dumps(list(listen)))
    conf.insert_json5("connect/endpoints", json.dumps(list(connect)))
    conf.insert_json5("scouting/multicast/enabled", json.dumps(multicast_scouting))
    # We publish express at REAL_TIME priority: one message per batch.  zenoh's default
    # queue of 2 batches drops a message (CongestionControl.DROP, after 1 ms) as soon as its
    # tx thread stalls for a couple of milliseconds; 16 batches ride out such stalls.
    conf.insert_json5("transport/link/tx/queue/size/real_time", str(TX_QUEUE_BATCHES))
    # No shared memory: zenoh 1.10's default sends payloads over 3 kB between local processes
    # through the sender's 16 MiB SHM pool, and a receiver maps (and keeps) the pool of every
    # new sender: +19 MB per connecting peer that sends one such payload (the soak's floods
    # grew the hand ~37 MB each).  Our messages are under 2 kB and cross hosts in production,
    # so SHM buys nothing here (tests/teleop/transport/test_zenoh_shm.py).
    conf.insert_json5("transport/shared_memory/enabled", "false")
    return conf


class ZenohBus:
    """One service's zenoh session (implements :class:`~teleop.transport.bus.Bus`)."""

    def __init__(self, role: str, *, session: str = "default",
                 links: LinksConfig | None = None, zenoh_cfg: ZenohConfig | None = None,
                 clock: Clock | None = None, listen: Sequence[str] | None = None,
                 connect: Sequence[str] | None = None, shared_clock: bool = True,
                 drop_stale: bool = True, gil_switch_interval_s: float | None = 1e-4,
                 extra_config: Mapping[str, str] | None = None,
                 energy_jump_max_j: float = math.inf,
                 seq_jump_max: int | None = None, announce: bool = True) -> None:
        self.role = check_role(role)
        if gil_switch_interval_s is not None and sys.getswitchinterval() > gil_switch_interval_s:
            sys.setswitchinterval(gil_switch_interval_s)
        self.session_name = check_session(session)
        zcfg = zenoh_cfg or ZenohConfig()
        self._clock = clock or MonotonicClock()
        self._shared_clock = shared_clock
        d_listen, d_connect = role_endpoints(role, zcfg)
        self.listen = list(d_listen if listen is None else listen)
        self.connect = list(d_connect if connect is None else connect)
        try:
            conf = zenoh_config(zcfg.mode, self.listen, self.connect, zcfg.multicast_scouting)
            for key, value in (extra_config or {}).items():  # zenoh key -> JSON5 (secure mode)
                conf.insert_json5(key, value)
        except zenoh.ZError as exc:
            raise self._open_error(exc) from None
        self._decoder = SafeDecoder(f"zenoh:{role}")
        self._inboxes: dict[str, Inbox] = make_inboxes(role, links or LinksConfig(),
                                                       self._decoder, drop_stale,
                                                       energy_jump_max_j, seq_jump_max)
        self._arrivals: dict[str, collections.deque[tuple[bytes, float]]] = {
            s: collections.deque() for s in self._inboxes}
        self._data_event = threading.Event()
        self._alive: set[str] = set()
        self._reset_from: set[str] = set()
        self._closed = False
        try:
            self._session = zenoh.open(conf)
        except zenoh.ZError as exc:
            raise self._open_error(exc) from None
        try:
            self._publishers = {
                name: self._session.declare_publisher(
                    data_key(session, name), congestion_control=zenoh.CongestionControl.DROP,
                    priority=zenoh.Priority.REAL_TIME, express=True)
                for name, spec in SIGNALS.items() if spec.sender == role}
            self._subscribers = [
                self._session.declare_subscriber(data_key(session, name), self._on_data(name))
                for name in self._inboxes]
            self._liveliness = zcfg.liveliness
            self._token: Any = None
            if announce:
                self.announce()
            self._live_sub = self._session.liveliness().declare_subscriber(
                liveliness_pattern(session), self._on_liveliness, history=True)
            # who runs here, for a service about to start (teleop.transport.roster)
            self._roster_key = roster_key(session, role)
            self._roster = self._session.declare_queryable(self._roster_key, self._on_roster)
        except BaseException:
            self._session.close()
            raise

    def announce(self) -> None:
        """Declare this service's liveliness token (once): peers take it as "ready to tick".
        ``announce=False`` at construction defers it, so a service can finish its slow set-up
        after opening the bus without its peers starting on it."""
        if self._token is None and self._liveliness:
            self._token = self._session.liveliness().declare_token(
                liveliness_key(self.session_name, self.role))

    def _open_error(self, exc: Exception) -> ConfigError:
        """A one-line user error for a zenoh session that cannot be set up."""
        msg = str(exc).split(" at /", 1)[0].strip()
        return ConfigError(f"zenoh ({self.role}): cannot open a session listening on "
                           f"{self.listen or '[]'} and connecting to {self.connect or '[]'}: "
                           f"{msg}")

    @classmethod
    def from_config(cls, role: str, cfg: TeleopConfig, **kwargs: object) -> ZenohBus:
        """A bus for ``role`` from the ``session``, ``zenoh`` and ``links`` sections."""
        kwargs.setdefault("shared_clock", cfg.zenoh.shared_clock)
        kwargs.setdefault("energy_jump_max_j", cfg.safety.energy_jump_max_j)
        kwargs.setdefault("seq_jump_max", cfg.safety.seq_jump_max)
        if "extra_config" not in kwargs:  # TLS, auth and ACL when security.enabled
            from teleop.security.zenoh_secure import secure_zenoh_config

            listen = kwargs.get("listen")  # explicit endpoints override the config's
            kwargs["extra_config"] = secure_zenoh_config(
                cfg, role, listening=None if listen is None else bool(listen))
        return cls(role, session=cfg.session.name, links=cfg.links, zenoh_cfg=cfg.zenoh,
                   **kwargs)  # type: ignore[arg-type]

    # -- zenoh callbacks (zenoh threads): only append / set operations ------------------
    def _on_data(self, signal: str):  # noqa: ANN202 - a zenoh callback
        queue = self._arrivals[signal]
        clock = self._clock

        def callback(sample: zenoh.Sample) -> None:
            now = clock.now_s()
            sent = now
            att = sample.attachment
            if att is not None:
                raw = att.to_bytes()
                if len(raw) == _STAMP.size:
                    stamp = _STAMP.unpack(raw)[0]
                    # trust only a plausible stamp (finite, not after arrival, recent)
                    if now - MAX_STAMP_AGE_S <= stamp <= now:
                        sent = stamp
            queue.append((sample.payload.to_bytes(), sent if self._shared_clock else now))
            self._data_event.set()

        return callback

    def _on_liveliness(self, sample: zenoh.Sample) -> None:
        role = role_from_key(str(sample.key_expr))
        if role is None:
            return
        if sample.kind == zenoh.SampleKind.PUT:
            self._alive.add(role)
            self._reset_from.add(role)
        else:
            self._alive.discard(role)

    def _on_roster(self, query: zenoh.Query) -> None:
        if not self._closed:
            # on our own key: the query's is a pattern, and zenoh keeps one answer per key
            query.reply(self._roster_key, encode_reply(self.role, tuple(self._alive)))

    # -- Bus ---------------------------------------------------------------------------
    def publish(self, signal: str, msg: Message) -> None:
        """Encode and put ``msg`` with the send time attached (never blocks: drops)."""
        check_publish(self.role, signal, msg)
        if self._closed:
            return
        self._publishers[signal].put(encode(msg), attachment=_STAMP.pack(self._clock.now_s()))

    def receive(self, signal: str) -> list[Received]:
        """Move arrivals into the delay line and release what is due now."""
        inbox = check_receive(self.role, self._inboxes, signal)
        if self._reset_from:
            for role in list(self._reset_from):
                self._reset_from.discard(role)
                for i in self._inboxes.values():
                    if i.spec.sender == role:  # a new sender epoch (see bus.py)
                        i.reset_seq()
                        i.drop_in_flight()
        queue = self._arrivals[signal]
        return inbox.arrive_and_release(_drain(queue), self._clock.now_s())

    def alive(self, role: str) -> bool:
        """Our own role while open; a peer while its liveliness token is present."""
        check_role(role)
        if role == self.role:
            return not self._closed
        return role in self._alive

    def peers_alive(self) -> dict[str, bool]:
        """``alive`` of every role."""
        return {r: self.alive(r) for r in ROLES}

    def stats(self) -> BusStats:
        """Rejections and per-link counters."""
        return BusStats(self.role, self._decoder.counts(),
                        tuple(i.stats() for i in self._inboxes.values()))

    def wait_for_data(self, timeout_s: float) -> bool:
        """Block until something arrives (or ``timeout_s``); True if something did."""
        got = self._data_event.wait(timeout_s)
        self._data_event.clear()
        return got

    def wait(self, timeout_s: float, spin_s: float = 150e-6) -> bool:
        """Block until data arrives, a delayed message falls due, or ``timeout_s`` passes.

        Sleeps on an event and spins the last ``spin_s`` before a release, so a loop of
        ``wait`` + ``receive`` delivers delayed messages within a few microseconds of their
        release time.  Returns True if new data arrived.
        """
        now = self._clock.now_s()
        deadline = now + timeout_s
        nxt = self.next_release_s()
        due = nxt is not None and nxt < deadline
        if due:
            deadline = nxt  # type: ignore[assignment]
        if deadline - now > spin_s and self.wait_for_data(deadline - now - (spin_s if due else 0)):
            return True
        while due and self._clock.now_s() < deadline:
            if self._data_event.is_set():
                self._data_event.clear()
                return True
        return False

    def next_release_s(self) -> float | None:
        """Earliest release time among messages already in the delay lines."""
        times = [t for i in self._inboxes.values() if (t := i.next_release_s()) is not None]
        return min(times) if times else None

    def close(self) -> None:
        """Undeclare everything and close the session (idempotent)."""
        if self._closed:
            return
        self._closed = True
        for sub in self._subscribers:
            sub.undeclare()
        self._live_sub.undeclare()
        self._roster.undeclare()
        for pub in self._publishers.values():
            pub.undeclare()
        if self._token is not None:
            self._token.undeclare()
        self._session.close()

    def __enter__(self) -> ZenohBus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
