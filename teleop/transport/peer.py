"""A stand-alone peer process for transport tests and ``teleop bench transport``.

Run as ``python -m teleop.transport.peer MODE [options]``; it prints ``READY`` when its
zenoh declarations are done, runs until its stdin closes (or ``--max-s``), then prints one
line ``RESULT <json>`` and exits after closing its session.  Modes:

* ``echo``: a ``controller`` :class:`ZenohBus`; every ``master_state`` received (through
  the delay line) is answered with a ``force_command`` of the same ``seq``; reports the
  achieved forward delays.
* ``count``: like echo, but only counts (throughput).
* ``idle``: a bus that only holds its liveliness token (liveliness tests).
* ``raw-echo``: a bare zenoh session echoing ``bench/<session>/ping`` on
  ``bench/<session>/pong`` from the callback (no codec, no delay line).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import queue
import socket
import subprocess
import sys
import threading
from collections.abc import Sequence

from teleop.config import load_config
from teleop.messages import ForceCommand, Header
from teleop.transport.clock import MonotonicClock
from teleop.transport.zenoh_bus import ZenohBus, zenoh_config

#: Spin this long before a release instead of sleeping (ZenohBus lowers the GIL switch
#: interval so zenoh's callback thread is not starved meanwhile).
SPIN_S = 150e-6


def free_tcp_endpoint() -> str:
    """``tcp/127.0.0.1:<port>`` with a port that was free a moment ago."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{s.getsockname()[1]}"


class PeerProcess:
    """A peer in a spawned subprocess (``sys.executable``, never a fork)."""

    def __init__(self, mode: str, args: Sequence[str] = (), ready_timeout_s: float = 20.0) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "teleop.transport.peer", mode, *args],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        self._lines: queue.Queue[str | None] = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()
        if self._next_line(ready_timeout_s) != "READY":
            self.kill()
            raise RuntimeError(f"peer {mode} did not start")

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self._lines.put(line.strip())
        self._lines.put(None)

    def _next_line(self, timeout_s: float) -> str | None:
        try:
            return self._lines.get(timeout=timeout_s)
        except queue.Empty:
            return None

    def stop(self, timeout_s: float = 20.0) -> dict[str, object]:
        """Close its stdin, wait for ``RESULT`` and the exit; returns the result."""
        assert self.proc.stdin is not None
        self.proc.stdin.close()
        result: dict[str, object] = {}
        while (line := self._next_line(timeout_s)) is not None:
            if line.startswith("RESULT "):
                result = json.loads(line[7:])
        try:
            self.proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self.kill()
            raise RuntimeError("peer did not exit") from None
        return result

    def kill(self) -> None:
        """SIGKILL (no clean-up: the peer's links just drop)."""
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(10.0)
        if self.proc.stdin is not None and not self.proc.stdin.closed:
            with contextlib.suppress(OSError):
                self.proc.stdin.close()


def _stdin_closed(stop: threading.Event) -> None:
    sys.stdin.read()
    stop.set()


def _result(obj: dict[str, object]) -> None:
    print("RESULT " + json.dumps(obj), flush=True)


def _run_raw(args: argparse.Namespace, stop: threading.Event) -> None:
    import zenoh

    session = zenoh.open(zenoh_config("peer", args.listen, args.connect))
    pong = session.declare_publisher(f"bench/{args.session}/pong", express=True,
                                     priority=zenoh.Priority.REAL_TIME)
    count = [0]

    def echo(sample: zenoh.Sample) -> None:
        pong.put(sample.payload.to_bytes())
        count[0] += 1

    sub = session.declare_subscriber(f"bench/{args.session}/ping", echo)
    token = session.liveliness().declare_token(f"bench/{args.session}/raw-echo")
    print("READY", flush=True)
    stop.wait(args.max_s)
    sub.undeclare()
    token.undeclare()
    pong.undeclare()
    session.close()
    _result({"echoed": count[0]})


def _serve(bus: ZenohBus, mode: str, stop: threading.Event) -> dict[str, object]:
    clock = MonotonicClock()
    delays_us: list[float] = []
    first = last = None
    while not stop.is_set():
        bus.wait(0.002, SPIN_S)
        for r in bus.receive("master_state"):
            delays_us.append(r.delay_s * 1e6)
            last = r.received_t_s
            first = first if first is not None else r.received_t_s
            if mode == "echo":
                h = Header(r.message.header.seq, clock.now_s(), 0.0)
                bus.publish("force_command", ForceCommand(h, 0.0))
    st = bus.stats()
    link = st.link("master_state")
    return {"delays_us": delays_us, "received": len(delays_us), "arrived": link.arrived,
            "lost": link.lost, "first_t_s": first, "last_t_s": last,
            "rejects": dict(st.rejects.by_reason)}


def main(argv: list[str] | None = None) -> int:
    """Entry point of the peer process."""
    p = argparse.ArgumentParser(prog="python -m teleop.transport.peer")
    p.add_argument("mode", choices=("echo", "count", "idle", "raw-echo"))
    p.add_argument("--session", default="bench")
    p.add_argument("--role", default="controller")
    p.add_argument("--listen", action="append", default=[])
    p.add_argument("--connect", action="append", default=[])
    p.add_argument("--set", dest="overrides", action="append", default=[])
    p.add_argument("--max-s", type=float, default=60.0)
    args = p.parse_args(argv)
    stop = threading.Event()
    threading.Thread(target=_stdin_closed, args=(stop,), daemon=True).start()
    if args.mode == "raw-echo":
        _run_raw(args, stop)
        return 0
    cfg = load_config(None, args.overrides)
    bus = ZenohBus(args.role, session=args.session, links=cfg.links, zenoh_cfg=cfg.zenoh,
                   listen=args.listen, connect=args.connect)
    try:
        print("READY", flush=True)
        if args.mode == "idle":
            stop.wait(args.max_s)
            result: dict[str, object] = {}
        else:
            timer = threading.Timer(args.max_s, stop.set)
            timer.daemon = True
            timer.start()
            result = _serve(bus, args.mode, stop)
    finally:
        bus.close()
    _result(result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
