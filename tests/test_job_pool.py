"""The tests' lockstep pool (``tests/job_pool.py``) hands back the run the test would have
made itself: a run in a spawned worker is bit for bit the in-process run (lockstep digests)."""

from __future__ import annotations

from services.lockstep import run_lockstep
from teleop.config import load_config
from tests.job_pool import JobPool, lockstep
from tests.services.lockstep_digest import digest


def test_a_pooled_run_is_the_in_process_run() -> None:
    cfg = load_config(None, ["links.master_controller.delay_s=0.05",
                             "links.master_controller.loss=0.2"])
    with JobPool({"a": (lockstep, (cfg, 0.5, 7)), "b": (lockstep, (cfg, 0.3, 8))},
                      workers=2) as pool:
        pooled = pool.result("a"), pool.result("b")
    assert digest(pooled[0]) == digest(run_lockstep(cfg, 0.5, seed=7))
    assert digest(pooled[1]) == digest(run_lockstep(cfg, 0.3, seed=8))


def test_without_workers_a_job_runs_here_once() -> None:
    calls: list[int] = []

    def job(x: int) -> int:
        calls.append(x)
        return 2 * x

    with JobPool({"x": (job, (3,))}, workers=1) as pool:
        assert pool.result("x") == 6 and pool.result("x") == 6
    assert calls == [3]
