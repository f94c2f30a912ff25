"""Independent simulations on every core (``sim/parallel_runs.py``): the order of the jobs, no
pool waiting on itself, and the same diagnosis on one thread and on several."""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import pytest

from sim import parallel_runs
from sim.parallel_runs import pmap, thread_count
from teleop.errors import UserInputError


def test_results_come_back_in_the_order_of_the_jobs(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TELEOP_THREADS", "4")

    def slow_first(i: int) -> int:  # the first jobs finish last
        time.sleep(0.02 * (6 - i))
        return i * i

    assert pmap(slow_first, range(6)) == [i * i for i in range(6)]


def test_a_map_inside_a_map_finishes(monkeypatch: pytest.MonkeyPatch) -> None:
    """A fit's finite differences run inside fits run side by side: the inner map must not
    wait for threads its own callers hold."""
    monkeypatch.setenv("TELEOP_THREADS", "2")
    out: list[list[list[int]]] = []
    worker = threading.Thread(
        target=lambda: out.append(pmap(lambda i: pmap(lambda j: 10 * i + j, range(3)),
                                       range(4))), daemon=True)
    worker.start()
    worker.join(timeout=20.0)
    assert out == [[[10 * i + j for j in range(3)] for i in range(4)]]


def test_one_thread_runs_the_jobs_in_the_caller(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TELEOP_THREADS", "1")
    here = threading.current_thread()
    assert pmap(lambda _: threading.current_thread() is here, range(3)) == [True] * 3


@pytest.mark.parametrize("value", ["0", "-2", "two", "1.5"])
def test_a_bad_thread_count_is_a_clear_error(monkeypatch: pytest.MonkeyPatch,
                                             value: str) -> None:
    monkeypatch.setenv("TELEOP_THREADS", value)
    with pytest.raises(UserInputError, match="TELEOP_THREADS"):
        thread_count()


def test_the_default_is_one_thread_per_core_at_most_the_cap(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("TELEOP_THREADS", raising=False)
    assert 1 <= thread_count() <= parallel_runs.MAX_THREADS


def test_the_compiled_finger_kernel_releases_the_gil() -> None:
    """Without ``nogil`` the threads would take turns: no faster than one."""
    from sim.compiled_dynamic import simulate_rows

    assert simulate_rows.targetoptions.get("nogil") is True


@pytest.mark.slow
def test_a_finger_diagnosis_is_the_same_on_one_thread_and_on_three(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from teleop.cli import main

    rec = tmp_path / "r.csv"
    assert main(["sim", "force-blocks", "--duration", "6", "--rate-hz", "1000", "--effect",
                 "coulomb_friction=1", "--noise", "--out", str(rec)]) == 0
    docs = []
    for n in ("1", "3"):
        monkeypatch.setenv("TELEOP_THREADS", n)
        out = tmp_path / f"d{n}.json"
        assert main(["diagnose", str(rec), "--model", "finger", "--json", str(out)]) == 0
        docs.append(json.loads(out.read_text()))
    assert docs[0] == docs[1]
    assert docs[0]["effects"]  # the fits ran (screening, candidates, the chosen effect's)


def test_a_bad_thread_count_stops_the_finger_diagnosis_first(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
        ) -> None:
    """Exit 2 and one line naming the variable, before any fitting starts."""
    from teleop.cli import main

    rec = tmp_path / "r.csv"
    assert main(["sim", "force-blocks", "--duration", "2", "--rate-hz", "200", "--out",
                 str(rec)]) == 0
    capsys.readouterr()
    monkeypatch.setenv("TELEOP_THREADS", "x")
    assert main(["diagnose", str(rec), "--model", "finger"]) == 2
    out = capsys.readouterr()
    assert "TELEOP_THREADS" in out.err and "fitting" not in out.out + out.err
