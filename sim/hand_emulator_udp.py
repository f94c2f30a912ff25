"""The emulated brain board on UDP: a real-time loop around :class:`BrainBoardModel`.

Unicast (default): the board binds ``address:port`` and sends its state packets to whoever
sent it the last valid command (nothing before the first one).  Multicast: it binds the
port, joins ``address`` (a multicast group, 224.0.0.124 on the real hand) on ``interface``
with multicast loopback on (so a PC process on the same host hears it) and sends to the
group; its own state packets looping back are skipped by length.

Example::

    board = UdpBrainBoard(model, BoardFaults(), "127.0.0.1", 0)
    host, port = board.open()
    board.serve(duration_s=5.0)
"""

from __future__ import annotations

import heapq
import select
import socket
import time
from itertools import count

from sim.hand_emulator import BrainBoardModel
from sim.hand_emulator_faults import BoardFaults, encode_with_faults
from teleop.devices.brain_board_link import open_udp
from teleop.devices.brain_board_packets import PALM_LEN, STATE_LEN, decode_command
from teleop.errors import DecodeError

MAX_BEHIND_S = 0.1  # a state schedule further behind than this restarts from now


class UdpBrainBoard:
    """Serve a :class:`BrainBoardModel` on UDP in real time."""

    def __init__(self, model: BrainBoardModel, faults: BoardFaults, address: str, port: int,
                 multicast: bool = False, interface: str = "") -> None:
        import random

        self.model = model
        self.faults = faults
        self.address = address
        self.port = port
        self.multicast = multicast
        self.interface = interface
        self.sock: socket.socket | None = None
        self.peer: tuple[str, int] | None = None
        self.rng = random.Random(faults.seed)
        self.held: dict[int, int] = {}
        self.fault_counts: dict[str, int] = {}
        self.bad_commands: dict[str, int] = {}
        self.states = 0  # state packets made
        self.sent = 0  # datagrams sent
        self.schedule_resets = 0
        self.first_command_s: float | None = None  # board time of the first valid command
        self._stop = False

    def open(self) -> tuple[str, int]:
        """Bind; returns the address and port the board listens on."""
        self.sock = open_udp(self.address, self.port, self.multicast, self.interface, True)
        host, port = self.sock.getsockname()[:2]
        return (self.address if self.multicast else host), port

    def stop(self) -> None:
        """Ask :meth:`serve` to return (from a signal handler or another thread)."""
        self._stop = True

    def _dest(self) -> tuple[str, int] | None:
        return (self.address, self.port) if self.multicast else self.peer

    def _receive(self, t_s: float) -> None:
        assert self.sock is not None
        while True:
            try:
                data, addr = self.sock.recvfrom(2048)
            except (BlockingIOError, InterruptedError):
                return
            if self.multicast and len(data) in (STATE_LEN, STATE_LEN + PALM_LEN):
                continue  # our own state packet looping back
            try:
                pkt = decode_command(data)
            except DecodeError as exc:
                self.bad_commands[exc.reason] = self.bad_commands.get(exc.reason, 0) + 1
                continue
            self.peer = addr[:2]
            if self.first_command_s is None:
                self.first_command_s = t_s
            self.model.handle(pkt, t_s)

    def serve(self, duration_s: float | None = None) -> None:
        """Run until :meth:`stop` or ``duration_s``."""
        if self.sock is None:
            self.open()
        assert self.sock is not None
        if not self.model.hand.started:
            self.model.start()
        t0 = time.monotonic()
        next_state = 0.0
        queue: list[tuple[float, int, bytes]] = []
        order = count()
        while not self._stop:
            t = time.monotonic() - t0
            if duration_s is not None and t >= duration_s:
                return
            due = min([next_state] + [q[0] for q in queue[:1]])
            try:
                ready, _, _ = select.select([self.sock], [], [], max(0.0, due - t))
            except InterruptedError:
                continue
            t = time.monotonic() - t0
            if ready:
                self._receive(t)
            if t >= next_state:
                state = self.model.state_at(t)
                self.states += 1
                driven_s = -1.0 if self.first_command_s is None else t - self.first_command_s
                for out in encode_with_faults(state, driven_s, self.faults, self.rng,
                                              self.held, self.fault_counts):
                    heapq.heappush(queue, (t + out.delay_s, next(order), out.data))
                next_state += self.model.period_s()
                if t - next_state > MAX_BEHIND_S:
                    next_state = t + self.model.period_s()
                    self.schedule_resets += 1
            while queue and queue[0][0] <= t:
                data = heapq.heappop(queue)[2]
                dest = self._dest()
                if dest is None:
                    self.fault_counts["no_peer"] = self.fault_counts.get("no_peer", 0) + 1
                    continue
                try:
                    self.sock.sendto(data, dest)
                    self.sent += 1
                except OSError:
                    self.fault_counts["send_error"] = self.fault_counts.get("send_error", 0) + 1

    def close(self) -> None:
        """Close the socket."""
        if self.sock is not None:
            self.sock.close()
            self.sock = None

    def summary(self) -> dict[str, object]:
        """Counters for the exit line and ``--json``."""
        return {"states": self.states, "sent": self.sent,
                "commands": self.model.packets_in, "bad_commands": dict(self.bad_commands),
                "faults": dict(self.fault_counts), "schedule_resets": self.schedule_resets}
