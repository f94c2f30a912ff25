"""One malloc arena keeps a service's memory flat over backlogs that different threads take
(a real process, glibc's allocator; the mutant is glibc's default of 8 arenas per core)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from services.heap import M_ARENA_MAX, _libc_mallopt, limit_arenas

ROOT = Path(__file__).resolve().parents[2]

# Four receive threads stay alive, as zenoh's do, each with its first allocation made (so each
# has its arena when there is no limit). Then each in turn takes a backlog: 30 MB in 2 kB
# blocks, every 50th kept for good (what is still in use when the backlog has drained), the
# rest freed. The limit is set first, as services.process does before the bus opens. RSS is
# read from /proc/self/status after every backlog.
CHILD = """
import sys, threading
sys.path.insert(0, sys.argv[2])
from services.heap import limit_arenas
limit_arenas(int(sys.argv[1]))
def rss_mb():
    for line in open("/proc/self/status"):
        if line.startswith("VmRSS"):
            return int(line.split()[1]) / 1024
keep = []
go = [threading.Event() for _ in range(4)]
done = [threading.Event() for _ in range(4)]
def receiver(k):
    warm = bytearray(3000)  # this thread's first malloc: its arena, if it may have one
    go[k].wait()
    blobs = [bytes(2000) + bytes([i % 251]) for i in range(15000)]
    keep.extend(blobs[::50])
    del blobs
    done[k].set()
    del warm
threads = [threading.Thread(target=receiver, args=(k,)) for k in range(4)]
for t in threads:
    t.start()
print(rss_mb())
for k in range(4):
    go[k].set()
    done[k].wait()
    print(rss_mb())
for t in threads:
    t.join()
"""


def _run(arenas: int) -> list[float]:
    out = subprocess.run([sys.executable, "-c", CHILD, str(arenas), str(ROOT)],
                         capture_output=True, text=True, check=True, timeout=60)
    return [float(x) for x in out.stdout.split()]


needs_glibc = pytest.mark.skipif(_libc_mallopt() is None,
                                 reason="no mallopt in this C library (not glibc)")


@needs_glibc
def test_one_arena_keeps_memory_flat_over_backlogs_taken_by_different_threads() -> None:
    rss = _run(1)
    first = rss[1] - rss[0]
    assert first > 20.0, f"the first backlog did not build up (RSS {rss})"
    # the three later backlogs reuse the first one's freed chunks: only what is kept
    # (3 x 0.6 MB) and a little slack
    assert rss[4] - rss[1] < 5.0, f"RSS {rss} MB with one arena"


@needs_glibc
def test_mutant_default_arenas_each_thread_keeps_its_backlog() -> None:
    rss = _run(0)
    assert rss[4] - rss[1] > 60.0, f"RSS {rss} MB with glibc's default arenas"


def test_the_limit_is_mallopt_arena_max_and_zero_leaves_the_default() -> None:
    calls: list[tuple[int, int]] = []

    def mallopt(param: int, value: int) -> int:
        calls.append((param, value))
        return 1

    assert not limit_arenas(0, mallopt) and calls == []
    assert limit_arenas(2, mallopt) and calls == [(M_ARENA_MAX, 2)]
    assert not limit_arenas(1, lambda _p, _v: 0)  # glibc refused
