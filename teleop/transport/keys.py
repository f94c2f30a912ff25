"""The zenoh key space and the signal table: the only place keys are built.

Keys are ``teleop/<session>/<role>/<signal>`` where ``<role>`` is the *sending* service.
Every signal has exactly one sender and one receiver role; the link and the direction it
travels are derived from those two roles:

==============  ==========  ==========  =================  =========
signal          sender      receiver    link               direction
==============  ==========  ==========  =================  =========
master_state    master      controller  master_controller  forward
force_command   controller  master      master_controller  backward
hand_command    controller  hand        controller_hand    forward
hand_state      hand        controller  controller_hand    backward
==============  ==========  ==========  =================  =========
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from teleop.errors import ConfigError
from teleop.messages import ForceCommand, HandCommand, HandState, MasterState

ROLES: tuple[str, ...] = ("master", "controller", "hand")
LIVELINESS_SIGNAL = "alive"
ROSTER_SIGNAL = "roster"
_NAME_RE = re.compile(r"^[A-Za-z0-9_.\-]+$")


@dataclass(frozen=True, slots=True)
class SignalSpec:
    """One signal: who sends it, who receives it, its message type and its link."""

    name: str
    sender: str
    receiver: str
    msg_type: type
    link: str  # attribute name in teleop.config.transport.LinksConfig
    forward: bool  # master->controller and controller->hand are forward


def link_between(sender: str, receiver: str) -> tuple[str, bool]:
    """``(link name, forward?)`` of the link carrying messages from ``sender`` to ``receiver``."""
    pair = {sender, receiver}
    if pair == {"master", "controller"}:
        return "master_controller", sender == "master"
    if pair == {"controller", "hand"}:
        return "controller_hand", sender == "controller"
    raise ValueError(f"no link between {sender!r} and {receiver!r}")


def _spec(name: str, sender: str, receiver: str, msg_type: type) -> SignalSpec:
    link, forward = link_between(sender, receiver)
    return SignalSpec(name, sender, receiver, msg_type, link, forward)


SIGNALS: dict[str, SignalSpec] = {
    s.name: s
    for s in (
        _spec("master_state", "master", "controller", MasterState),
        _spec("force_command", "controller", "master", ForceCommand),
        _spec("hand_command", "controller", "hand", HandCommand),
        _spec("hand_state", "hand", "controller", HandState),
    )
}


def check_role(role: str) -> str:
    """``role`` if it is one of :data:`ROLES`, else ValueError."""
    if role not in ROLES:
        raise ValueError(f"unknown role {role!r} (expected one of {', '.join(ROLES)})")
    return role


def signal_spec(signal: str) -> SignalSpec:
    """The :class:`SignalSpec` of ``signal`` (KeyError names the known signals)."""
    try:
        return SIGNALS[signal]
    except KeyError:
        raise KeyError(f"unknown signal {signal!r} (known: {', '.join(SIGNALS)})") from None


def check_session(session: str) -> str:
    """A session name usable as one key chunk; :class:`ConfigError` otherwise."""
    if not _NAME_RE.match(session):
        raise ConfigError(f"session.name = {session!r}: use letters, digits, '_', '-' or '.' "
                          "(it is one chunk of the zenoh key)")
    return session


def data_key(session: str, signal: str) -> str:
    """``teleop/<session>/<sender role>/<signal>``."""
    spec = signal_spec(signal)
    return f"teleop/{check_session(session)}/{spec.sender}/{signal}"


def liveliness_key(session: str, role: str) -> str:
    """The liveliness token key of the service ``role``: ``teleop/<session>/<role>/alive``."""
    return f"teleop/{check_session(session)}/{check_role(role)}/{LIVELINESS_SIGNAL}"


def liveliness_pattern(session: str) -> str:
    """Key expression matching every service's liveliness token in ``session``."""
    return f"teleop/{check_session(session)}/*/{LIVELINESS_SIGNAL}"


def roster_key(session: str, role: str) -> str:
    """The key of the service ``role``'s roster queryable: ``teleop/<session>/<role>/roster``
    (who it sees running; :mod:`teleop.transport.roster`)."""
    return f"teleop/{check_session(session)}/{check_role(role)}/{ROSTER_SIGNAL}"


def roster_pattern(session: str) -> str:
    """Key expression matching every service's roster queryable in ``session``."""
    return f"teleop/{check_session(session)}/*/{ROSTER_SIGNAL}"


def role_from_key(key: str) -> str | None:
    """The role chunk of a ``teleop/<session>/<role>/...`` key (None if malformed)."""
    parts = key.split("/")
    if len(parts) < 4 or parts[0] != "teleop" or parts[2] not in ROLES:
        return None
    return parts[2]


def signals_received_by(role: str) -> tuple[str, ...]:
    """Names of the signals ``role`` receives."""
    check_role(role)
    return tuple(s.name for s in SIGNALS.values() if s.receiver == role)
