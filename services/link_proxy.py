"""A TCP relay on 127.0.0.1 between a service and the controller, which can cut the link.

``teleop faults --soak`` points the master and the hand at a relay each instead of at the
controller's endpoint, so cutting a link is real: :meth:`LinkProxy.cut` closes every relayed
connection and the listening socket (the zenoh sessions see their link drop and reconnect
attempts refused); :meth:`LinkProxy.restore` listens again on the same port, and the
services' zenoh sessions reconnect by themselves.
"""

from __future__ import annotations

import contextlib
import socket
import threading

CHUNK = 65536


class LinkProxy:
    """Relays ``127.0.0.1:port`` to ``127.0.0.1:target_port`` (threads, one per direction)."""

    def __init__(self, target_port: int, port: int = 0) -> None:
        self.target_port = target_port
        self._lock = threading.Lock()
        self._socks: list[socket.socket] = []
        self._listener: socket.socket | None = None
        self.port = port
        self.cuts = 0
        self.connections = 0
        self.restore()

    def restore(self) -> None:
        """Listen (again) on :attr:`port` and relay what connects."""
        lst = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        lst.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        lst.bind(("127.0.0.1", self.port))
        lst.listen(8)
        self.port = int(lst.getsockname()[1])
        with self._lock:
            self._listener = lst
        threading.Thread(target=self._accept, args=(lst,), daemon=True).start()

    def cut(self) -> None:
        """Close the listening socket and every relayed connection."""
        with self._lock:
            lst, self._listener = self._listener, None
            socks, self._socks = self._socks, []
        self.cuts += 1
        for s in ([lst] if lst is not None else []) + socks:
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)
            s.close()

    def close(self) -> None:
        """Cut for good."""
        self.cut()

    def _accept(self, lst: socket.socket) -> None:
        while True:
            try:
                down, _ = lst.accept()
            except OSError:
                return  # cut
            try:
                up = socket.create_connection(("127.0.0.1", self.target_port), timeout=2.0)
                up.settimeout(None)
            except OSError:
                down.close()
                continue
            for s in (down, up):
                s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            with self._lock:
                if self._listener is not lst:  # cut meanwhile
                    down.close()
                    up.close()
                    return
                self._socks += [down, up]
                self.connections += 1
            threading.Thread(target=self._pump, args=(down, up), daemon=True).start()
            threading.Thread(target=self._pump, args=(up, down), daemon=True).start()

    @staticmethod
    def _pump(src: socket.socket, dst: socket.socket) -> None:
        try:
            while data := src.recv(CHUNK):
                dst.sendall(data)
        except OSError:
            pass
        for s in (src, dst):
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)
