"""Fixed-rate loops on an injected clock, with timing statistics.

:class:`RateLoop` calls ``tick(t_s)`` once per period.  On a real-time clock it waits with
sleep-then-spin: it sleeps until ``spin_s`` before the deadline, then spins on the clock (Linux
sleeps overshoot by 50-100 us, which a 1 kHz loop cannot afford).  A tick that overruns by more
than ``catchup_periods`` skips the missed deadlines instead of bursting to catch up; shorter
overruns are caught up by ticking at once.  On a
:class:`~teleop.transport.clock.VirtualClock` the loop jumps the clock to each deadline.

The lateness of every tick (start time minus its deadline) is kept for ``teleop bench loop``.
After a stall the loop re-bases on the next deadline, so ``lateness_s`` (and its percentiles)
describes the scheduling jitter without the stalls; each stall's true lateness (measured from
the first deadline it missed) is kept in ``stall_lateness_s`` and counted in
``<role>_lateness_max_us``, reported beside the p99 with the stall count.
"""

from __future__ import annotations

import contextlib
import math
import os
import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from teleop.transport.clock import Clock, MonotonicClock, VirtualClock, wait_until


@dataclass(frozen=True, slots=True)
class LoopStats:
    """Timing of a finished loop."""

    rate_hz: float  # configured rate
    ticks: int
    skipped: int  # deadlines dropped after overruns
    elapsed_s: float
    lateness_s: np.ndarray  # per tick: start time minus deadline
    stall_ticks: tuple[int, ...] = ()  # tick indices after which deadlines were skipped
    stall_lateness_s: tuple[float, ...] = ()  # per stall: start time minus the first missed
    tick_s: np.ndarray | None = None  # per tick: how long tick() took

    @property
    def achieved_rate_hz(self) -> float:
        """Ticks per second over the run."""
        return self.ticks / self.elapsed_s if self.elapsed_s > 0 else math.nan

    def lateness_percentile_s(self, q: float) -> float:
        """A percentile (0-100) of the per-tick lateness."""
        if self.lateness_s.size == 0:
            return math.nan
        return float(np.percentile(self.lateness_s, q))

    @property
    def max_lateness_s(self) -> float:
        """The worst lateness of any tick, stalls included (nan without ticks)."""
        if self.lateness_s.size == 0:
            return math.nan
        return max((float(np.max(self.lateness_s)), *self.stall_lateness_s))

    def figures(self, prefix: str) -> dict[str, float]:
        """Flat figures with units in the keys, for ``teleop bench``.

        ``_lateness_p50_us``/``_p99_us`` are re-based after each stall (scheduling jitter);
        ``_lateness_max_us`` and ``_stall_lateness_max_us`` include the stalls' true
        lateness, and ``_stalls`` counts them: read the p99 with those beside it.
        """
        return {
            f"{prefix}_rate_hz": self.achieved_rate_hz,
            f"{prefix}_ticks": float(self.ticks),
            f"{prefix}_skipped": float(self.skipped),
            f"{prefix}_lateness_p50_us": self.lateness_percentile_s(50) * 1e6,
            f"{prefix}_lateness_p99_us": self.lateness_percentile_s(99) * 1e6,
            f"{prefix}_lateness_max_us": self.max_lateness_s * 1e6,
            f"{prefix}_stall_lateness_max_us": max(self.stall_lateness_s, default=0.0) * 1e6,
            f"{prefix}_tick_p99_us": float(np.percentile(self.tick_s, 99)) * 1e6
            if self.tick_s is not None and self.tick_s.size else math.nan,
            f"{prefix}_tick_max_us": float(np.max(self.tick_s)) * 1e6
            if self.tick_s is not None and self.tick_s.size else math.nan,
            f"{prefix}_stalls": float(len(self.stall_ticks)),
            f"{prefix}_first_stall_tick": float(self.stall_ticks[0]) if self.stall_ticks
            else -1.0,
        }


class RateLoop:
    """Run ``tick(t_s)`` at ``rate_hz`` on ``clock`` until stopped or ``duration_s`` passes."""

    def __init__(self, rate_hz: float, clock: Clock | None = None,
                 spin_s: float = 3e-4, catchup_periods: int = 20) -> None:
        if not rate_hz > 0:
            raise ValueError("rate_hz must be > 0")
        self.rate_hz = rate_hz
        self.period_s = 1.0 / rate_hz
        self.clock: Clock = clock if clock is not None else MonotonicClock()
        self.spin_s = spin_s
        self.catchup_periods = catchup_periods
        self.stop_event = threading.Event()

    def stop(self) -> None:
        """Ask the loop to finish after the current tick (thread- and signal-safe)."""
        self.stop_event.set()

    def _wait_until(self, deadline: float) -> float:
        if isinstance(self.clock, VirtualClock):  # virtual time: jump to the deadline
            if deadline > self.clock.now_s():
                self.clock.set(deadline)
            return self.clock.now_s()
        return wait_until(self.clock, deadline, self.spin_s)

    def run(self, tick: Callable[[float], None], duration_s: float | None = None,
            should_stop: Callable[[], bool] | None = None,
            timing: Callable[[float, float, float], None] | None = None) -> LoopStats:
        """Tick until :meth:`stop`, ``should_stop()`` or ``duration_s``; return the timing.

        ``timing(deadline_s, lateness_s, stall_lateness_s)`` (``stall_lateness_s`` 0 unless the
        tick ended a stall), when given, gets every tick's timing instead of the returned
        :class:`LoopStats` (whose arrays are then empty): memory stays flat however long the
        loop runs (``teleop faults --soak``)."""
        start = self.clock.now_s()
        end = math.inf if duration_s is None else start + duration_s
        lateness: list[float] = []
        skipped = 0
        stalls: list[int] = []
        stall_late: list[float] = []
        durations: list[float] = []
        n_ticks = 0  # ticks reported through ``timing`` (not kept)
        k = 0
        while not self.stop_event.is_set():
            deadline = start + k * self.period_s
            if deadline >= end:
                break
            now = self._wait_until(deadline)
            late = now - deadline
            stall_s = 0.0
            if late > self.catchup_periods * self.period_s:  # long stall: drop deadlines
                missed = int(late // self.period_s)
                skipped += missed
                stalls.append(len(lateness) + n_ticks)
                stall_late.append(late)
                stall_s = late
                k += missed
                deadline = start + k * self.period_s
                late = now - deadline
            if timing is None:
                lateness.append(late)
            else:
                n_ticks += 1
                timing(deadline, late, stall_s)
            tick(deadline)
            if timing is None:
                durations.append(self.clock.now_s() - now)
            k += 1
            if should_stop is not None and should_stop():
                break
        elapsed = self.clock.now_s() - start
        return LoopStats(rate_hz=self.rate_hz, ticks=len(lateness) + n_ticks, skipped=skipped,
                         elapsed_s=elapsed, lateness_s=np.asarray(lateness, dtype=float),
                         stall_ticks=tuple(stalls), stall_lateness_s=tuple(stall_late),
                         tick_s=np.asarray(durations, dtype=float))


def try_realtime_priority(priority: int = 20) -> bool:
    """Put the calling thread under ``SCHED_FIFO`` at ``priority`` (Linux, needs the
    privilege); returns whether it worked.  A 1 kHz loop on a busy machine then wakes on time
    (p99 lateness tens of microseconds instead of milliseconds); the kernel's RT throttling
    (95% per second by default) keeps a runaway loop from locking the machine.
    """
    if not hasattr(os, "sched_setscheduler"):
        return False
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (OSError, ValueError):
        return False
    # the process's other threads (zenoh's I/O and callback threads) too, one step lower:
    # a callback thread holding the GIL must not be preempted by unrelated processes while
    # the loop thread waits for the GIL (priority inversion)
    try:
        tids = [int(t) for t in os.listdir("/proc/self/task")]
    except OSError:
        tids = []
    me = threading.get_native_id()
    for tid in tids:
        if tid != me:
            with contextlib.suppress(OSError, ValueError):
                os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(max(priority - 1, 1)))
    return True
