"""Give a service's freed heap back to the operating system.

A service that is stalled (SIGSTOP, a long VM pause) receives its whole backlog at once when it
runs again: zenoh's receive threads and the callbacks allocate for every queued message, and
glibc keeps the freed chunks in its per-thread arenas. The process then holds that
high-water mark for the rest of its life (measured: +9-13 MB after one 3 s stop of a 1 kHz
receiver, none of it in use). ``malloc_trim(0)`` returns the free pages of every arena; a
daemon thread calls it every ``period_s`` (0.3-2 ms per call here, off the service's loop).

Only glibc has ``malloc_trim``; elsewhere the trimmer does nothing and says so
(:attr:`HeapTrimmer.available`).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import threading
import time
from collections.abc import Callable


def _libc_trim() -> Callable[[int], int] | None:
    """glibc's ``malloc_trim``, or None where the C library has none."""
    name = ctypes.util.find_library("c")
    if name is None:
        return None
    try:
        fn = ctypes.CDLL(name).malloc_trim
    except (OSError, AttributeError):
        return None
    fn.argtypes = [ctypes.c_size_t]
    fn.restype = ctypes.c_int
    return fn


class HeapTrimmer:
    """Calls ``malloc_trim(0)`` every ``period_s`` on a daemon thread until :meth:`stop`.

    ``trims`` counts the calls and ``longest_s`` is the slowest one, for the service's figures.
    ``trim`` is injectable (tests, other C libraries)."""

    def __init__(self, period_s: float,
                 trim: Callable[[int], int] | None = None) -> None:
        if period_s < 0.0:
            raise ValueError(f"heap trim period must be >= 0 s, got {period_s}")
        self.period_s = period_s
        self._trim = trim if trim is not None else _libc_trim()
        self.available = self._trim is not None
        self.trims = 0
        self.longest_s = 0.0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def trim_now(self) -> None:
        """One trim, timed."""
        if self._trim is None:
            return
        t0 = time.perf_counter()
        self._trim(0)
        self.longest_s = max(self.longest_s, time.perf_counter() - t0)
        self.trims += 1

    def start(self) -> HeapTrimmer:
        """Start the thread (nothing when the period is 0 or there is no ``malloc_trim``)."""
        if self.period_s > 0.0 and self.available and self._thread is None:
            self._thread = threading.Thread(target=self._run, name="heap-trim", daemon=True)
            self._thread.start()
        return self

    def _run(self) -> None:
        while not self._stop.wait(self.period_s):
            self.trim_now()

    def stop(self) -> None:
        """Stop the thread and wait for it (a trim in progress finishes)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
