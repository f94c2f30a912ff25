"""The heap trimmer gives a backlog's freed memory back (a real process, glibc's malloc_trim)
and trims only when the resident size has jumped."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from services.heap import REARM_S, HeapTrimmer
from teleop.config.session import SessionConfig

ROOT = Path(__file__).resolve().parents[2]

# A worker thread allocates 60 MB in 2 kB blocks (its own malloc arena, like zenoh's receive
# threads after a stall) and keeps every 50th block, so the freed memory is fragmented and glibc
# keeps it. The process then polls the trimmer as a service loop does (its base taken before
# the backlog). RSS is read from /proc/self/status here, not through the trimmer's own gauge.
CHILD = """
import sys, threading
sys.path.insert(0, sys.argv[2])
from services.heap import REARM_S, HeapTrimmer
from teleop.config.session import SessionConfig
def rss_mb():
    for line in open("/proc/self/status"):
        if line.startswith("VmRSS"):
            return int(line.split()[1]) / 1024
trimmer = HeapTrimmer(float(sys.argv[1]))
trimmer.poll()
keep = []
def work():
    blobs = [bytes(2000) + bytes([i % 251]) for i in range(30000)]
    keep.extend(blobs[::50])
t = threading.Thread(target=work)
t.start()
t.join()
before = rss_mb()
for _ in range(3):
    trimmer.poll()
print(before, rss_mb(), trimmer.trims)
"""


def _run(threshold_mb: float) -> tuple[float, float, int]:
    out = subprocess.run([sys.executable, "-c", CHILD, str(threshold_mb), str(ROOT)],
                         capture_output=True, text=True, check=True, timeout=60)
    before, after, trims = out.stdout.split()
    return float(before), float(after), int(trims)


needs_glibc = pytest.mark.skipif(not HeapTrimmer(1.0).available,
                                 reason="no malloc_trim in this C library (not glibc)")


@needs_glibc
def test_the_trimmer_returns_a_fragmented_backlog_to_the_os_once() -> None:
    # the services' default threshold: what every service runs with
    before, after, trims = _run(SessionConfig().heap_trim_mb)
    assert before > 50.0, f"the backlog did not build up ({before:.1f} MB)"
    assert trims == 1  # the jump is trimmed once; the next polls find nothing grown
    assert before - after > 30.0, f"RSS {before:.1f} -> {after:.1f} MB"


@needs_glibc
def test_mutant_without_trimming_the_backlog_stays() -> None:
    before, after, trims = _run(0.0)
    assert trims == 0
    assert after > before - 5.0, f"RSS {before:.1f} -> {after:.1f} MB without trimming"


def _fake(rss: list[float], clock: list[float] | None = None, rearm_s: float = REARM_S
          ) -> tuple[HeapTrimmer, list[int]]:
    calls: list[int] = []
    now = clock if clock is not None else [0.0]

    def trim(pad: int) -> int:
        calls.append(pad)
        rss[0] -= 5.0  # a trim gives 5 MB back
        return 1

    return HeapTrimmer(4.0, trim=trim, rss_mb=lambda: rss[0], now_s=lambda: now[0],
                       rearm_s=rearm_s), calls


def _regrowing(rearm_s: float) -> int:
    """Trims in 60 one-second polls when every trim's pages are faulted straight back in
    (RSS back to 60 MB at once): the trigger would fire at every poll."""
    rss, clock = [50.0], [0.0]
    trimmer, calls = _fake(rss, clock, rearm_s)
    trimmer.poll()
    for _ in range(60):
        clock[0] += 1.0
        rss[0] = 60.0
        trimmer.poll()
    return len(calls)


def test_a_trim_whose_memory_comes_straight_back_waits_to_be_rearmed() -> None:
    assert _regrowing(REARM_S) == 2  # at 1 s and at 31 s (60 s of polls)


def test_mutant_without_rearm_delay_trims_every_second() -> None:
    assert _regrowing(0.0) == 60


def test_a_trim_only_after_the_resident_size_jumped_by_the_threshold() -> None:
    rss, clock = [50.0], [0.0]
    trimmer, calls = _fake(rss, clock)
    assert not trimmer.poll()  # the first poll sets the base
    rss[0] = 53.9
    assert not trimmer.poll() and calls == []
    rss[0] = 60.0
    assert trimmer.poll() and calls == [0]
    assert trimmer.base_mb == 55.0 and trimmer.trims == 1
    assert not trimmer.poll()  # nothing grew since
    rss[0] = 45.0
    assert not trimmer.poll() and trimmer.base_mb == 45.0  # memory went down: a lower base
    rss[0] = 49.5
    assert not trimmer.poll()  # grown enough, but within REARM_S of the last trim
    clock[0] += REARM_S
    assert trimmer.poll() and trimmer.trims == 2


def test_threshold_zero_never_trims_and_a_bad_threshold_is_refused() -> None:
    rss = [50.0]
    trimmer, calls = _fake(rss)
    trimmer.threshold_mb = 0.0
    rss[0] = 500.0
    assert not trimmer.poll() and calls == []
    for bad in (-1.0, float("nan")):
        with pytest.raises(ValueError, match="heap trim threshold"):
            HeapTrimmer(bad)


def test_no_proc_means_no_trim() -> None:
    calls: list[int] = []
    trimmer = HeapTrimmer(1.0, trim=lambda pad: calls.append(pad) or 1,
                          rss_mb=lambda: float("nan"))
    assert not trimmer.poll() and not trimmer.poll() and calls == []
