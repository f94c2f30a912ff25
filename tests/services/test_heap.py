"""The heap trimmer gives a backlog's freed memory back (a real process, glibc's malloc_trim)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from services.heap import HeapTrimmer

ROOT = Path(__file__).resolve().parents[2]

# A worker thread allocates 60 MB in 2 kB blocks (its own malloc arena, like zenoh's receive
# threads after a stall) and keeps every 50th block, so the freed memory is fragmented and glibc
# keeps it. The process then runs the trimmer for a second.
CHILD = """
import sys, threading, time
sys.path.insert(0, sys.argv[2])
from services.heap import HeapTrimmer
def rss_mb():
    for line in open("/proc/self/status"):
        if line.startswith("VmRSS"):
            return int(line.split()[1]) / 1024
keep = []
def work():
    blobs = [bytes(2000) + bytes([i % 251]) for i in range(30000)]
    keep.extend(blobs[::50])
t = threading.Thread(target=work)
t.start()
t.join()
before = rss_mb()
trimmer = HeapTrimmer(float(sys.argv[1])).start()
time.sleep(1.0)
trimmer.stop()
print(before, rss_mb(), trimmer.trims)
"""


def _run(period_s: float) -> tuple[float, float, int]:
    out = subprocess.run([sys.executable, "-c", CHILD, str(period_s), str(ROOT)],
                         capture_output=True, text=True, check=True, timeout=60)
    before, after, trims = out.stdout.split()
    return float(before), float(after), int(trims)


needs_glibc = pytest.mark.skipif(not HeapTrimmer(1.0).available,
                                 reason="no malloc_trim in this C library (not glibc)")


@needs_glibc
def test_the_trimmer_returns_a_fragmented_backlog_to_the_os() -> None:
    before, after, trims = _run(0.2)
    assert before > 50.0, f"the backlog did not build up ({before:.1f} MB)"
    assert trims >= 3
    assert before - after > 30.0, f"RSS {before:.1f} -> {after:.1f} MB"


@needs_glibc
def test_mutant_without_trimming_the_backlog_stays() -> None:
    before, after, trims = _run(0.0)
    assert trims == 0
    assert after > before - 5.0, f"RSS {before:.1f} -> {after:.1f} MB without trimming"


def test_an_injected_trim_is_called_on_its_period_and_stops() -> None:
    calls: list[int] = []
    trimmer = HeapTrimmer(0.02, trim=lambda pad: calls.append(pad) or 1).start()
    time.sleep(0.2)
    trimmer.stop()
    n = len(calls)
    time.sleep(0.06)
    assert n >= 4 and calls == [0] * n and len(calls) == n
    assert trimmer.trims == n and trimmer.longest_s >= 0.0


def test_period_zero_starts_no_thread_and_a_negative_period_is_refused() -> None:
    calls: list[int] = []
    trimmer = HeapTrimmer(0.0, trim=lambda pad: calls.append(pad) or 1).start()
    time.sleep(0.05)
    trimmer.stop()
    assert calls == []
    with pytest.raises(ValueError, match="heap trim period"):
        HeapTrimmer(-1.0)
