"""`teleop.transport.endpoint_check`: a taken listen endpoint is seen, a free one is not."""

from __future__ import annotations

import errno
import socket

import pytest

from teleop.transport.endpoint_check import endpoint_address, endpoint_bind_errno


def endpoint_in_use(endpoint: str) -> bool:
    return endpoint_bind_errno(endpoint) == errno.EADDRINUSE

@pytest.mark.parametrize(("endpoint", "expected"), [
    ("tcp/127.0.0.1:7447", (socket.SOCK_STREAM, "127.0.0.1", 7447)),
    ("tls/[::1]:7447#iface=lo", (socket.SOCK_STREAM, "::1", 7447)),
    ("udp/localhost:7000?rel=0", (socket.SOCK_DGRAM, "localhost", 7000)),
    ("QUIC/10.0.0.2:7447", (socket.SOCK_DGRAM, "10.0.0.2", 7447)),
    ("unixsock-stream//tmp/z.sock", None),  # no IP address: left to zenoh
    ("tcp/127.0.0.1:0", None),  # any port: nothing to check
    ("tcp/:7447", None),
    ("tcp/127.0.0.1:70000", None),
    ("127.0.0.1:7447", None),  # no protocol
])
def test_endpoint_addresses(endpoint: str, expected: object) -> None:
    assert endpoint_address(endpoint) == expected


def test_a_listening_port_is_in_use_and_free_once_closed() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        for proto in ("tcp", "tls", "ws"):
            assert endpoint_in_use(f"{proto}/127.0.0.1:{port}")
        assert endpoint_in_use(f"tcp/localhost:{port}")
        assert not endpoint_in_use(f"udp/127.0.0.1:{port}")  # another socket kind
    assert not endpoint_in_use(f"tcp/127.0.0.1:{port}")


def test_a_udp_port_in_use() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
        assert endpoint_in_use(f"udp/127.0.0.1:{port}")
        assert endpoint_in_use(f"quic/127.0.0.1:{port}")


def test_a_closed_connection_in_time_wait_does_not_count() -> None:
    """A port whose last session just ended (its connections in TIME_WAIT) is free to listen
    on again, as for zenoh's listener."""
    with socket.socket() as srv:
        srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        srv.bind(("127.0.0.1", 0))
        srv.listen()
        port = srv.getsockname()[1]
        cli = socket.create_connection(("127.0.0.1", port))
        conn, _ = srv.accept()
        conn.close()  # the server side closes first: its end goes to TIME_WAIT
        cli.close()
    assert not endpoint_in_use(f"tcp/127.0.0.1:{port}")


@pytest.mark.parametrize("endpoint", [
    "tcp/192.0.2.1:7447",  # not this machine's address (TEST-NET-1): not "in use"
    "tcp/no-such-host.invalid:7447",  # does not resolve
    "tcp/127.0.0.1:notaport",
])
def test_what_the_check_cannot_judge_is_left_to_zenoh(endpoint: str) -> None:
    assert not endpoint_in_use(endpoint)


def test_why_a_listener_could_not_bind() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        assert endpoint_bind_errno(f"tcp/127.0.0.1:{port}") == errno.EADDRINUSE
    assert endpoint_bind_errno(f"tcp/127.0.0.1:{port}") is None
    assert endpoint_bind_errno("tcp/192.0.2.1:7447") == errno.EADDRNOTAVAIL  # TEST-NET-1
    assert endpoint_bind_errno("udp/192.0.2.1:7447") == errno.EADDRNOTAVAIL
    assert endpoint_bind_errno("tcp/no-such-host.invalid:7447") is None
    assert endpoint_bind_errno("unixsock-stream//tmp/z.sock") is None
