"""Jobs run by priority, serially or on a ``spawn`` process pool; a finished job may add more.

The delay sweep's bisection runs depend on the grid runs of their own controller at zero loss
only, and each bisection step on the one before.  Submitting the whole grid to a pool first
and bisecting afterwards leaves all workers but one idle for the bisection's length; with
:class:`JobQueue` those grid runs go first, a bisection step goes out as soon as it can (ahead
of the waiting grid runs), and the rest of the grid fills the other workers meanwhile.  Only
``workers`` jobs are in flight at once, so a job added later is not queued behind the pool's
backlog.  What a job computes does not depend on when or where it runs (every run's seeds
come from its point), so the order changes the wall time, never a result.
"""

from __future__ import annotations

import heapq
import itertools
import multiprocessing
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import Any

__all__ = ["JobQueue"]

Then = Callable[[Any], None]


class JobQueue:
    """Run ``fn(*args)`` jobs lowest priority first; ``then(result)`` runs in this process.

    ``workers <= 1`` runs the jobs here, one after another (the same priorities)."""

    def __init__(self, workers: int) -> None:
        self.workers = max(1, workers)
        self._ex: ProcessPoolExecutor | None = None
        if workers > 1:
            self._ex = ProcessPoolExecutor(workers,
                                           mp_context=multiprocessing.get_context("spawn"))
        self._heap: list[tuple[tuple[float, ...], int, Callable[..., Any], tuple[Any, ...],
                               Then]] = []
        self._count = itertools.count()

    def add(self, priority: tuple[float, ...], fn: Callable[..., Any], args: tuple[Any, ...],
            then: Then) -> None:
        """Queue a job (ties keep the order they were added in)."""
        heapq.heappush(self._heap, (priority, next(self._count), fn, args, then))

    def run(self) -> None:
        """Run until no job is queued or in flight (``then`` may add jobs)."""
        if self._ex is None:
            while self._heap:
                _, _, fn, args, then = heapq.heappop(self._heap)
                then(fn(*args))
            return
        flying: dict[Future[Any], tuple[int, Then]] = {}
        while self._heap or flying:
            while self._heap and len(flying) < self.workers:
                _, n, fn, args, then = heapq.heappop(self._heap)
                flying[self._ex.submit(fn, *args)] = (n, then)
            done, _ = wait(flying, return_when=FIRST_COMPLETED)
            for fut in sorted(done, key=lambda f: flying[f][0]):
                _, then = flying.pop(fut)
                then(fut.result())

    def close(self) -> None:
        """Shut the pool down (idempotent)."""
        if self._ex is not None:
            self._ex.shutdown(cancel_futures=True)
            self._ex = None
