"""Independent simulations on every core: a thread map that keeps the order of its jobs.

A diagnosis of a finger recording is hundreds of simulations that do not depend on each other:
the screening grids of the catalog effects, the two probe runs per wavenumber of the shaft
ripple scan, the columns of every fit's finite-difference Jacobian.  The compiled finger
kernel (:func:`sim.compiled_dynamic.simulate_rows`) releases the GIL while it runs, so threads
run such simulations side by side (processes would have to ship the recording to each one).
Each job computes exactly what it computes alone, and :func:`pmap` returns the results in the
order of the jobs, so a diagnosis is the same, to the last bit, on any number of threads
(``tests/sim/test_parallel_runs.py``).  Its signature, ``pmap(fun, iterable)``, is the one
``scipy.optimize.least_squares`` asks of its ``workers`` (the finite differences).

``TELEOP_THREADS`` (an integer >= 1) sets the number of threads; the default is one per core
this process may run on, at most :data:`MAX_THREADS`.  A ``pmap`` inside a ``pmap`` (a fit's
finite differences inside fits run side by side) uses a pool of its own, so no pool waits on
itself; the threads then outnumber the cores for a while, which costs nothing when the jobs
are compiled simulations that do not hold the GIL.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

from teleop.errors import UserInputError

__all__ = ["MAX_THREADS", "pmap", "thread_count"]

T = TypeVar("T")
R = TypeVar("R")

#: at most this many threads by default (more cores than this: set ``TELEOP_THREADS``)
MAX_THREADS = 8

#: nested maps (a fit's Jacobian inside fits run side by side) get a pool of their own per
#: level, so no pool waits on itself; deeper than this a map runs in its caller's thread
MAX_DEPTH = 2

_pools: dict[int, tuple[int, ThreadPoolExecutor]] = {}
_lock = threading.Lock()
_local = threading.local()


def thread_count() -> int:
    """Threads :func:`pmap` uses: ``TELEOP_THREADS``, else one per usable core (at most
    :data:`MAX_THREADS`)."""
    env = os.environ.get("TELEOP_THREADS", "").strip()
    if env:
        try:
            n = int(env)
        except ValueError:
            n = 0
        if n < 1:
            raise UserInputError(f"TELEOP_THREADS={env!r}: expected an integer >= 1")
        return n
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not on Linux
        cores = os.cpu_count() or 1
    return max(1, min(cores, MAX_THREADS))


def _set_depth(depth: int) -> None:
    _local.depth = depth


def _executor(depth: int, n: int) -> ThreadPoolExecutor:
    with _lock:
        hit = _pools.get(depth)
        if hit is None or hit[0] != n:
            if hit is not None:
                hit[1].shutdown(wait=False)
            hit = (n, ThreadPoolExecutor(n, thread_name_prefix=f"teleop-sim{depth}",
                                         initializer=_set_depth, initargs=(depth + 1,)))
            _pools[depth] = hit
        return hit[1]


def pmap(fn: Callable[[T], R], items: Iterable[T]) -> list[R]:
    """``[fn(x) for x in items]``, the calls spread over :func:`thread_count` threads."""
    jobs = list(items)
    n = thread_count()
    depth = getattr(_local, "depth", 0)
    if n <= 1 or len(jobs) <= 1 or depth >= MAX_DEPTH:
        return [fn(x) for x in jobs]
    return list(_executor(depth, n).map(fn, jobs))
