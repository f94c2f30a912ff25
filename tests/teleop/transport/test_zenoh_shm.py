"""A service's zenoh session does not grow by a shared-memory pool per connecting peer.

zenoh 1.10 sends payloads over 3 kB between local processes through the sender's 16 MiB
shared-memory pool when both sides allow it; the receiver maps, and keeps, the pool of every
new sender.  The services' config turns shared memory off, so peers that come and go (the
soak's flooder, a restarted controller) cost nothing; the mutant keeps zenoh's default and
grows ~19 MB per sender.  Senders are separate processes with zenoh's default config, as a
foreign peer would be."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import time

import pytest
import zenoh

from teleop.transport.zenoh_bus import zenoh_config

pytestmark = [pytest.mark.network, pytest.mark.slow]

SENDER = """
import json, sys, time, zenoh
c = zenoh.Config()
c.insert_json5("mode", '"peer"')
c.insert_json5("scouting/multicast/enabled", "false")
c.insert_json5("connect/endpoints", json.dumps([sys.argv[1]]))
s = zenoh.open(c)
time.sleep(0.3)
pub = s.declare_publisher("shm/test")
for _ in range(int(sys.argv[2])):
    pub.put(b"x" * 4200)
    time.sleep(0.001)
time.sleep(0.3)
pub.undeclare()
s.close()
"""


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _rss_mb() -> float:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS"):
                return int(line.split()[1]) / 1024.0
    raise AssertionError("no VmRSS")


def _growth_mb(conf: zenoh.Config, endpoint: str, senders: int = 3) -> tuple[float, int]:
    """RSS growth of a receiving session over ``senders`` successive foreign peers."""
    session = zenoh.open(conf)
    got = [0]
    sub = session.declare_subscriber("shm/**", lambda _s: got.__setitem__(0, got[0] + 1))
    try:
        time.sleep(0.3)
        subprocess.run([sys.executable, "-c", SENDER, endpoint, "50"], check=True, timeout=60)
        before = _rss_mb()  # after one sender: warm-up (buffers, first transport)
        for _ in range(senders):
            subprocess.run([sys.executable, "-c", SENDER, endpoint, "300"], check=True,
                           timeout=60)
        time.sleep(0.2)
        return _rss_mb() - before, got[0]
    finally:
        sub.undeclare()
        session.close()


def test_connecting_peers_do_not_grow_a_service_session() -> None:
    ep = f"tcp/127.0.0.1:{_port()}"
    growth, got = _growth_mb(zenoh_config("peer", [ep], []), ep)
    assert got > 500  # the payloads really arrived
    assert growth < 6.0, f"{growth:.1f} MB over three senders"


def test_mutant_zenoh_default_shared_memory_grows_per_sender() -> None:
    ep = f"tcp/127.0.0.1:{_port()}"
    conf = zenoh_config("peer", [ep], [])
    conf.insert_json5("transport/shared_memory/enabled", json.dumps(True))
    growth, got = _growth_mb(conf, ep)
    assert got > 500
    assert growth > 30.0, f"{growth:.1f} MB over three senders"
