"""The PC's UDP link to the brain board: one non-blocking socket, no protocol logic.

Multicast (the real hand): bind the board's port, join the group on the chosen interface,
multicast loopback off as the stock driver has it (on when the emulator runs on this host; the
link then skips its own looped-back command packets by length).  Unicast (the emulator on
loopback): an ephemeral local port; the board answers to where the commands come from.
"""

from __future__ import annotations

import socket

from teleop.devices.brain_board_packets import MODES_LEN, TARGETS_LEN

MAX_DATAGRAM = 2048


def open_udp(address: str, port: int, multicast: bool, interface: str,
             loopback: bool) -> socket.socket:
    """A non-blocking UDP socket bound for the brain-board protocol (either side)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM, socket.IPPROTO_UDP)
    try:
        if multicast:  # the PC and a same-host emulator both bind the group's port
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            sock.bind(("", port))
            iface = socket.inet_aton(interface or "0.0.0.0")
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP,
                            socket.inet_aton(address) + iface)
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, iface)
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, int(loopback))
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 1)
        else:
            sock.bind((address, port))
        sock.setblocking(False)
    except OSError:
        sock.close()
        raise
    return sock



class BoardLink:
    """Send packets to the board, drain what it sent (never blocks)."""

    def __init__(self, network: str, address: str, port: int, interface: str = "",
                 loopback: bool = False) -> None:
        self.multicast = network == "multicast"
        self.dest = (address, port)
        self.interface = interface
        self.loopback = loopback
        self.sock: socket.socket | None = None
        self.send_errors = 0

    def open(self) -> None:
        """Create and bind the socket (``OSError`` when the host refuses)."""
        if self.multicast:
            self.sock = open_udp(self.dest[0], self.dest[1], True, self.interface,
                                 self.loopback)
        else:
            local = "127.0.0.1" if self.dest[0].startswith("127.") else ""
            self.sock = open_udp(local, 0, False, "", False)

    def send(self, data: bytes) -> bool:
        """Send one packet; False (counted) when the host refused it."""
        if self.sock is None:
            return False
        try:
            self.sock.sendto(data, self.dest)
            return True
        except OSError:
            self.send_errors += 1
            return False

    def receive(self) -> list[bytes]:
        """Every datagram waiting (our own looped-back commands skipped)."""
        out: list[bytes] = []
        if self.sock is None:
            return out
        while True:
            try:
                data = self.sock.recv(MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError):
                return out
            except OSError:
                return out  # e.g. ICMP port unreachable reported on a unicast socket
            if self.multicast and len(data) in (MODES_LEN, TARGETS_LEN) and data[0] in (1, 2):
                continue
            out.append(data)

    def close(self) -> None:
        """Close the socket."""
        if self.sock is not None:
            self.sock.close()
            self.sock = None
