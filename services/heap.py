"""Give a service's freed heap back to the operating system after its memory jumps.

A service that is stalled (SIGSTOP, a long VM pause) receives its whole backlog at once when it
runs again: zenoh's receive threads and the callbacks allocate for every queued message, and
glibc keeps the freed chunks in its per-thread arenas. The process then holds that
high-water mark for the rest of its life (measured: +9-13 MB after one 3 s stop of a 1 kHz
receiver, none of it in use). ``malloc_trim(0)`` returns the free pages of every arena.

:meth:`HeapTrimmer.poll` is called by the service loop itself, in its once-a-second slot: it
reads the resident size (``/proc/self/statm``, ~10 us) and trims only when it has grown by
``threshold_mb`` since the last trim, so a trim (0.3-2 ms) is paid once after a backlog, not
periodically.  The loop's own thread trims: a trim on a background thread of normal priority
holds the arenas' locks while the real-time loop can preempt it.

**On by default** (``session.heap_trim_mb = 4``, at most one trim per :data:`REARM_S`).
It was off for a while because the soaks' master loop had more late ticks with it; paired
4-minute soaks (``teleop faults --soak 4 --fault-every 10``, trimmer on / off, load average
8-11) did not confirm that: the master trimmed 0 times in both runs with the trimmer, and
its late ticks (> 5 ms) were 3,883 / 4,649 and 13,588 / 14,391.  The master's late ticks
come with or without the trimmer (docs/faults.md).  A controller stalled for 3 s peaked at
66 MB in all runs and was back at 54-55 MB a second after the stall with the trimmer, at
66-68 MB to its end without.

Limiting the arenas instead (:func:`limit_arenas`, ``session.malloc_arenas = 1``) makes
successive backlogs reuse one arena (tests/services/test_heap_arenas.py) but does not return
the first one: the stalled controller of a soak with it kept 65 MB.

Only glibc has ``malloc_trim``; elsewhere the trimmer does nothing (:attr:`available`).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import math
import os
import time
from collections.abc import Callable
from typing import Any

_MB = 1024.0 * 1024.0


def _libc(symbol: str, *argtypes: Any) -> Any:
    """The C library's ``symbol`` returning an int, or None where it has none (not glibc)."""
    name = ctypes.util.find_library("c")
    if name is None:
        return None
    try:
        fn = getattr(ctypes.CDLL(name), symbol)
    except (OSError, AttributeError):
        return None
    fn.argtypes = list(argtypes)
    fn.restype = ctypes.c_int
    return fn


def _libc_trim() -> Callable[[int], int] | None:
    """glibc's ``malloc_trim``, or None where the C library has none."""
    return _libc("malloc_trim", ctypes.c_size_t)


M_ARENA_MAX = -8  # glibc's mallopt parameter number (malloc.h)


def limit_arenas(n: int, mallopt: Callable[[int, int], int] | None = None) -> bool:
    """Let glibc's malloc use at most ``n`` arenas in this process (0: leave its default, 8
    per core); True if the limit was set.  Call it before the threads start: glibc fixes the
    limit the first time a thread needs an arena of its own.  With one arena a backlog's
    freed chunks are reused by the next backlog whichever thread takes it, instead of each
    receive thread keeping a high-water mark of its own."""
    if n <= 0:
        return False
    fn = mallopt if mallopt is not None else _libc_mallopt()
    return fn is not None and fn(M_ARENA_MAX, n) == 1


def _libc_mallopt() -> Callable[[int, int], int] | None:
    """glibc's ``mallopt``, or None where the C library has none."""
    return _libc("mallopt", ctypes.c_int, ctypes.c_int)


def resident_mb() -> float:
    """This process's resident set size in MB (nan where ``/proc`` is missing)."""
    try:
        with open("/proc/self/statm", "rb") as f:
            pages = int(f.read().split()[1])
    except (OSError, ValueError, IndexError):
        return float("nan")
    return pages * os.sysconf("SC_PAGE_SIZE") / _MB


#: after a trim the trimmer waits this long before it may trim again, whatever the resident
#: size does: a trim whose pages are faulted straight back in cannot become a trim a second
REARM_S = 30.0


class HeapTrimmer:
    """Trims the heap when the resident size has grown ``threshold_mb`` since the last trim
    (0: never), at most once per :data:`REARM_S`.  ``trims`` counts the trims and
    ``longest_s`` is the slowest, for the service's figures; ``trim``, ``rss_mb`` and
    ``now_s`` are injectable (tests, other C libraries)."""

    def __init__(self, threshold_mb: float, trim: Callable[[int], int] | None = None,
                 rss_mb: Callable[[], float] = resident_mb,
                 now_s: Callable[[], float] = time.monotonic, rearm_s: float = REARM_S
                 ) -> None:
        if not threshold_mb >= 0.0:
            raise ValueError(f"heap trim threshold must be >= 0 MB, got {threshold_mb}")
        self.threshold_mb = threshold_mb
        self._trim = trim if trim is not None else _libc_trim()
        self._rss = rss_mb
        self._now = now_s
        self.rearm_s = rearm_s
        self._last_trim_s = -math.inf
        self.trims = 0
        self.longest_s = 0.0
        self.base_mb = float("nan")  # resident size after the last trim (or the first poll)

    @property
    def available(self) -> bool:
        """Whether there is a ``malloc_trim`` to call."""
        return self._trim is not None

    def trim_now(self) -> None:
        """One trim, timed; the resident size after it is the new base."""
        if self._trim is None:
            return
        t0 = time.perf_counter()
        self._trim(0)
        self.longest_s = max(self.longest_s, time.perf_counter() - t0)
        self.trims += 1
        self.base_mb = self._rss()
        self._last_trim_s = self._now()

    def poll(self) -> bool:
        """Trim if the resident size grew by the threshold since the base; True if it did."""
        if self.threshold_mb <= 0.0 or self._trim is None:
            return False
        rss = self._rss()
        if math.isnan(rss):  # no /proc: nothing to compare
            return False
        if not self.base_mb <= rss:  # first poll, or memory went down: a lower base
            self.base_mb = rss
            return False
        if rss - self.base_mb < self.threshold_mb:
            return False
        if self._now() - self._last_trim_s < self.rearm_s:  # not re-armed yet
            return False
        self.trim_now()
        return True
