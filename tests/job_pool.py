"""A test module's independent long jobs (lockstep runs, diagnoses), started together on a
small spawn pool.

CI runs pytest in one process on a two-core machine, so a module whose tests each run their
own lockstep runs (or a batch of diagnoses), one after another, leaves a core idle.  :class:`JobPool` submits every
run a module needs at once (in the order given: the order the tests ask for them, so the first
tests start while later runs are computed) to ``workers`` spawned processes and hands each test
its own run's result when it asks: the same call as in the test (a lockstep run is a pure
function of its config and seed; ``tests/test_job_pool.py`` holds a pooled run to
an in-process one bit for bit), only computed beside the others.  A job is a top-level
function and its arguments, so it pickles; runs with hooks that close over test state stay in
the test.

Usage (a module fixture)::

    @pytest.fixture(scope="module")
    def runs():
        with JobPool({"a": (lockstep, (cfg, 6.0, 3))}) as pool:
            yield pool

    def test_a(runs):
        r = runs.result("a")
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Hashable, Mapping
from concurrent.futures import Future, ProcessPoolExecutor
from typing import Any

from services.lockstep import LockstepResult, run_lockstep
from teleop.config import TeleopConfig

__all__ = ["JobPool", "lockstep"]

Job = tuple[Callable[..., Any], tuple[Any, ...]]


def lockstep(cfg: TeleopConfig, seconds: float, seed: int) -> LockstepResult:
    """``run_lockstep(cfg, seconds, seed=seed)`` (a picklable job function)."""
    return run_lockstep(cfg, seconds, seed=seed)


def _default_workers() -> int:
    """Two processes on a multi-core machine; one (the test's own process) under
    pytest-xdist, whose other worker already keeps the second core busy."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        return 1
    return min(2, os.cpu_count() or 1)


class JobPool:
    """Jobs ``key -> (fn, args)`` run on ``workers`` spawned processes, started in the
    mapping's order; :meth:`result` waits for one.  With one core (or
    ``workers <= 1``) each job runs here, when its result is first asked for."""

    def __init__(self, jobs: Mapping[Hashable, Job], workers: int | None = None) -> None:
        self._jobs = dict(jobs)
        self._done: dict[Hashable, Any] = {}
        n = _default_workers() if workers is None else workers
        self._ex: ProcessPoolExecutor | None = None
        self._futures: dict[Hashable, Future[Any]] = {}
        if n > 1:
            self._ex = ProcessPoolExecutor(n, mp_context=multiprocessing.get_context("spawn"))
            for key, (fn, args) in self._jobs.items():
                self._futures[key] = self._ex.submit(fn, *args)

    def result(self, key: Hashable) -> Any:
        """The result of job ``key`` (its exception, if it raised)."""
        if self._ex is not None:
            return self._futures[key].result()
        if key not in self._done:
            fn, args = self._jobs[key]
            self._done[key] = fn(*args)
        return self._done[key]

    def close(self) -> None:
        """Stop the pool (jobs not started are dropped)."""
        if self._ex is not None:
            self._ex.shutdown(cancel_futures=True)
            self._ex = None

    def __enter__(self) -> JobPool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

