"""An in-process bus on a (usually virtual) clock: deterministic lockstep runs.

All three services share one :class:`InProcessHub`; each gets a view with
:meth:`InProcessHub.bus`.  ``publish`` hands the message to the receiving view's delay line,
stamped with the hub clock; ``receive`` releases what is due at the clock's current time.
A message the codec round-trips exactly (:func:`~teleop.transport.exact.round_trips`: every
field of the type and in the range decode gives back) travels as the immutable object
itself, so the receiver gets what decoding its encoding would have given, without the
msgpack round trip; anything else is encoded and decoded through the checked codec path as
over the network (rejected with its reason), and so is every raw payload :meth:`inject`
puts on a link.  With a
:class:`~teleop.transport.clock.VirtualClock` the outcome depends only on the config seeds
and the order of calls.

Usage::

    clock = VirtualClock()
    hub = InProcessHub(cfg.links, clock, session=cfg.session.name)
    master, ctrl = hub.bus("master"), hub.bus("controller")
    master.publish("master_state", msg)
    clock.advance(0.001)
    for r in ctrl.receive("master_state"): ...
"""

from __future__ import annotations

import math
from dataclasses import replace

from teleop.config.schema import TeleopConfig
from teleop.config.transport import LinkConfig, LinksConfig
from teleop.messages import Message
from teleop.transport.bus import (
    BusStats,
    Inbox,
    Received,
    check_publish,
    check_receive,
    link_params,
    make_inboxes,
)
from teleop.transport.clock import Clock
from teleop.transport.codec import KINDS, encode
from teleop.transport.exact import round_trips
from teleop.transport.keys import SIGNALS, check_role, check_session
from teleop.transport.safe_decoder import SafeDecoder


class InProcessHub:
    """The shared medium of an in-process run: one clock, the links, the live views."""

    def __init__(self, links: LinksConfig, clock: Clock, session: str = "default",
                 drop_stale: bool = True, energy_jump_max_j: float = math.inf,
                 seq_jump_max: int | None = None) -> None:
        self.links = links
        self.clock = clock
        self.session = check_session(session)
        self.drop_stale = drop_stale
        self.energy_jump_max_j = energy_jump_max_j
        self.seq_jump_max = seq_jump_max
        self._views: dict[str, InProcessBus] = {}
        self._cut: set[str] = set()  # links cut by fault injection
        self.cut_dropped = 0  # messages lost on cut links

    @classmethod
    def from_config(cls, cfg: TeleopConfig, clock: Clock) -> InProcessHub:
        """A hub with ``cfg.links``, ``cfg.session.name``, ``safety.energy_jump_max_j`` and
        ``safety.seq_jump_max``."""
        return cls(cfg.links, clock, cfg.session.name,
                   energy_jump_max_j=cfg.safety.energy_jump_max_j,
                   seq_jump_max=cfg.safety.seq_jump_max)

    def bus(self, role: str) -> InProcessBus:
        """The view of service ``role`` (one live view per role).

        A role (re)joining is a new sender epoch, as when its liveliness token comes back
        on zenoh: every other view's inboxes of signals it sends reset their sequence filter
        and energy epoch, and drop what the previous incarnation still had in flight.
        """
        check_role(role)
        if role in self._views:
            raise ValueError(f"the in-process bus already has a live {role!r} view")
        for other in self._views.values():
            for inbox in other._inboxes.values():
                if inbox.spec.sender == role:
                    inbox.reset_seq()
                    inbox.drop_in_flight()
        view = InProcessBus(self, role)
        self._views[role] = view
        return view

    def next_release_s(self) -> float | None:
        """Earliest release time of any message in flight (to skip idle virtual time)."""
        times = [t for v in self._views.values() for t in v.next_release_times()]
        return min(times) if times else None

    def set_link(self, link: str, cfg: LinkConfig | None) -> None:
        """Fault injection: cut ``link`` (``None``: every message on it, both directions,
        is lost; liveliness is unaffected) or give it new impairments ``cfg`` from now on
        (messages already in flight keep their release times).  ``link`` is
        ``"master_controller"`` or ``"controller_hand"``."""
        if link not in ("master_controller", "controller_hand"):
            raise ValueError(f"unknown link {link!r}")
        if cfg is None:
            self._cut.add(link)
            return
        self._cut.discard(link)
        self.links = replace(self.links, **{link: cfg})
        for view in self._views.values():
            for inbox in view._inboxes.values():
                if inbox.spec.link == link:
                    inbox.params = link_params(self.links, inbox.signal)

    def _deliver(self, signal: str, payload: bytes | Message, t_s: float) -> None:
        spec = SIGNALS[signal]  # a known signal: publish checked it
        if spec.link in self._cut:
            self.cut_dropped += 1
            return
        view = self._views.get(spec.receiver)
        if view is not None:  # nobody listening: the message is gone, as on a network
            view._inboxes[signal].arrive(payload, t_s)

    def _is_alive(self, role: str) -> bool:
        return role in self._views

    def _drop(self, view: InProcessBus) -> None:
        if self._views.get(view.role) is view:
            del self._views[view.role]


class InProcessBus:
    """One service's view of an :class:`InProcessHub` (implements :class:`Bus`)."""

    def __init__(self, hub: InProcessHub, role: str) -> None:
        self.role = role
        self._hub = hub
        self._decoder = SafeDecoder(f"inproc:{role}")
        self._inboxes: dict[str, Inbox] = make_inboxes(role, hub.links, self._decoder,
                                                       hub.drop_stale, hub.energy_jump_max_j,
                                                       hub.seq_jump_max)
        self._closed = False

    def publish(self, signal: str, msg: Message) -> None:
        """Put ``msg`` on its link at the hub clock's time: as the object when the codec
        round-trips it exactly, else encoded (see the module docstring)."""
        spec = SIGNALS.get(signal)
        if spec is None or spec.sender != self.role or type(msg) is not spec.msg_type:
            check_publish(self.role, signal, msg)  # raises: a programming error
        if self._closed:
            return
        hub = self._hub
        hub._deliver(signal, msg if round_trips(msg) else encode(msg), hub.clock.now_s())

    def receive(self, signal: str) -> list[Received]:
        """Messages on ``signal`` due at the hub clock's time."""
        inbox = self._inboxes.get(signal)
        if inbox is None:
            inbox = check_receive(self.role, self._inboxes, signal)  # raises
        return inbox.release(self._hub.clock.now_s())

    def alive(self, role: str) -> bool:
        """Whether ``role`` has a live view on the hub."""
        if role in self._hub._views:  # a live view's role is a checked one
            return True
        return self._hub._is_alive(check_role(role))

    def stats(self) -> BusStats:
        """Rejections and per-link counters."""
        return BusStats(self.role, self._decoder.counts(),
                        tuple(i.stats() for i in self._inboxes.values()))

    def next_release_times(self) -> list[float]:
        """Release times of the next message of every received signal in flight."""
        return [t for i in self._inboxes.values() if (t := i.next_release_s()) is not None]

    def next_release_s(self) -> float | None:
        """Earliest release time among messages in flight to this view."""
        times = self.next_release_times()
        return min(times) if times else None

    def inject(self, signal: str, payload: bytes) -> None:
        """Put raw bytes on ``signal``'s link towards this view (tests: bad messages); they
        go through the checked decoder (a message object is encoded first, never passed)."""
        raw: object = encode(payload) if type(payload) in KINDS else payload
        check_receive(self.role, self._inboxes, signal).arrive(raw, self._hub.clock.now_s())  # type: ignore[arg-type]

    def close(self) -> None:
        """Leave the hub (peers see this role as not alive)."""
        if not self._closed:
            self._closed = True
            self._hub._drop(self)
