"""Is a zenoh listen endpoint already taken?  (``teleop up`` asks before it starts anything.)

``teleop up`` starts the controller listening on ``zenoh.endpoint`` and the master and hand
connecting to it, all three at once.  With another session (or any program) already
listening there, the new controller cannot bind and exits, but its master and hand have
meanwhile connected to the *running* session's controller: nothing moves (their sequence
numbers are behind the running peers', so the running controller drops what they send), yet
the run fails with exit status 1, a zenoh error and two services killed at the stop timeout,
and the running session loses ticks to the start-up.  Asking first turns that into one line
and exit status 2, with nothing started.

The check binds a socket of the endpoint's kind (``tcp``, ``tls`` and ``ws``: a TCP socket
with ``SO_REUSEADDR``, as a listener does, so connections lingering in ``TIME_WAIT`` do not
count; ``udp`` and ``quic``: a UDP socket) to its address and releases it at once.
``EADDRINUSE`` means taken; ``EADDRNOTAVAIL`` for every address the host resolves to means
it is not this machine's (a remote controller's address given to ``teleop up``, which starts
the controller here).  Anything else (a port below 1024, a name that does not resolve, a
protocol without an IP address such as ``unixsock-stream``, port 0) is left for zenoh to
report when the controller opens its session.  A check, not a lock: a program that takes the
port between this check and the controller's bind still fails the run the old way.
"""

from __future__ import annotations

import errno
import socket

from teleop.config.transport import ZenohConfig

__all__ = ["endpoint_address", "endpoint_bind_errno", "role_endpoints"]

def role_endpoints(role: str, zcfg: ZenohConfig) -> tuple[list[str], list[str]]:
    """``(listen, connect)`` of ``role``: the controller listens on ``zcfg.endpoint``.  (Here,
    not in :mod:`teleop.transport.zenoh_bus`, which imports zenoh: ``teleop up`` asks before
    it starts anything, without that start-up time.)"""
    listen, connect = list(zcfg.listen), list(zcfg.connect)
    if zcfg.endpoint:
        (listen if role == "controller" else connect).append(zcfg.endpoint)
    return listen, connect


#: zenoh protocol -> socket type of its listener
_SOCKET_TYPES = {"tcp": socket.SOCK_STREAM, "tls": socket.SOCK_STREAM,
                 "ws": socket.SOCK_STREAM, "udp": socket.SOCK_DGRAM,
                 "quic": socket.SOCK_DGRAM}


def endpoint_address(endpoint: str) -> tuple[int, str, int] | None:
    """``(socket type, host, port)`` of a zenoh endpoint ``proto/host:port[?meta][#conf]``
    (IPv6 hosts in brackets), or None for one this check does not cover (see the module
    docstring)."""
    proto, sep, rest = endpoint.strip().partition("/")
    kind = _SOCKET_TYPES.get(proto.lower())
    if not sep or kind is None:
        return None
    address = rest.split("#", 1)[0].split("?", 1)[0]
    host, sep, port_text = address.rpartition(":")
    if not sep or not port_text.isdigit():
        return None
    port = int(port_text)
    if host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    if not host or not 0 < port < 65536:
        return None
    return kind, host, port


def endpoint_bind_errno(endpoint: str) -> int | None:
    """Why a listener could not bind ``endpoint`` on this machine, as an errno:
    ``EADDRINUSE`` if one of its resolved addresses is taken, else ``EADDRNOTAVAIL`` if none
    of them is this machine's (a remote host's address), else None (free, or nothing this
    check judges: see the module docstring)."""
    parsed = endpoint_address(endpoint)
    if parsed is None:
        return None
    kind, host, port = parsed
    try:
        infos = socket.getaddrinfo(host, port, type=kind)
    except (OSError, UnicodeError):
        return None
    errors: list[int | None] = []
    for family, socktype, proto, _, addr in infos:
        try:
            with socket.socket(family, socktype, proto) as s:
                if socktype == socket.SOCK_STREAM:
                    s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
                s.bind(addr)
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                return errno.EADDRINUSE
            errors.append(exc.errno)
        else:
            errors.append(None)
    if errors and all(e == errno.EADDRNOTAVAIL for e in errors):
        return errno.EADDRNOTAVAIL
    return None

