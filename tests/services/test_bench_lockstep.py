"""``teleop bench lockstep``: both engines side by side, ratios and the profile split."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from services.bench_lockstep import bench_lockstep
from teleop.cli import main


def test_bench_lockstep_reports_both_engines_and_where_the_time_goes() -> None:
    fig = bench_lockstep(sim_time_s=0.5, repeats=1)
    for what in ("lockstep", "simhand"):
        py, co = fig[f"python_{what}_realtime_factor"], fig[f"compiled_{what}_realtime_factor"]
        assert py > 0.0 and co > 0.0
        assert fig[f"compiled_{what}_over_python"] == pytest.approx(co / py)
    shares = {k: v for k, v in fig.items() if k.startswith("profile_share_")}
    assert sum(shares.values()) == pytest.approx(1.0)
    assert shares["profile_share_transport"] > 0.0 and shares["profile_share_control"] > 0.0
    assert all(isinstance(v, float) for v in fig.values())


@pytest.mark.slow  # two subprocesses, each loading numba and the compiled engine
def test_bench_lockstep_runs_a_reference_tree_side_by_side() -> None:
    """``--reference DIR``: the reference tree's lockstep (here this very tree, in a
    subprocess) alternates with this one's; ratios are this tree over the reference."""
    tree = Path(__file__).resolve().parents[2]
    fig = bench_lockstep(sim_time_s=0.3, repeats=1, reference=str(tree))
    for eng in ("python", "compiled"):
        ref = fig[f"reference_{eng}_lockstep_realtime_factor"]
        assert ref > 0.0
        assert fig[f"compiled_lockstep_over_reference_{eng}"] == pytest.approx(
            fig["compiled_lockstep_realtime_factor"] / ref)


def test_bench_reference_must_be_a_source_tree(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "lockstep", "--reference", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--reference" in err[0] and "not a source tree" in err[0]
    assert main(["bench", "sim", "--reference", str(tmp_path)]) == 2


def test_bench_repeats_only_for_lockstep(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "sim", "--repeats", "3"]) == 2
    assert main(["bench", "lockstep", "--repeats", "0"]) == 2
    err = capsys.readouterr().err
    assert err.count("--repeats") == 2


def test_instructions_only_for_lockstep_and_need_valgrind(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "sim", "--instructions"]) == 2
    monkeypatch.setenv("PATH", "")  # no valgrind: refused before any timing
    assert main(["bench", "lockstep", "--instructions"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "--instructions" in err[0] and "valgrind not found" in err[1]


@pytest.mark.slow  # one process under valgrind, about 40 s
@pytest.mark.skipif(shutil.which("valgrind") is None, reason="needs valgrind")
def test_instructions_count_the_measured_run_only() -> None:
    """Twice the simulated time, about twice the instructions: start-up, imports and the
    warm-up (some 40 billion instructions, against tens of millions here) are not counted,
    nor the run before (both runs in one process, each counted from its own dump)."""
    from services.bench_instructions import count_instructions_each

    tree = Path(__file__).resolve().parents[2]
    short, long = count_instructions_each(tree, "python", (0.05, 0.1))
    assert 1e6 < short < 1e9
    assert 1.6 < long / short < 2.4
