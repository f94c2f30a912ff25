"""The faster lockstep gives the sweep the same answer: a short direct-control sweep (two grid
points and one bisection run) matches, row for row, the one recorded on main (55896c7) before
the lockstep was made faster (every JSON key but ``wall_s``, floats to 12 digits; the bracket and the prediction).

Record again only for an intended behaviour change: run the record's ``command`` with
``--json`` and keep its rows without ``wall_s`` (say so in the commit)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from teleop.cli import main

RECORD = json.loads((Path(__file__).parent / "data" / "sweep_direct_record.json").read_text())


def _rounded(a: object) -> object:
    """Floats to 12 significant digits: the lockstep's arithmetic is what must not move; the
    last digit does between machines and library builds (2026-11-26, a new machine with
    numpy 2.4.6, scipy 1.17.1, numba 0.68.1: ``hf_power_fraction`` 0.9797822279812575 ->
    ...574, the same with numpy 2.3, scipy 1.16 or numba 0.67 swapped in)."""
    if isinstance(a, float):
        return float(f"{a:.12g}")
    if isinstance(a, dict):
        return {k: _rounded(v) for k, v in a.items()}
    if isinstance(a, list):
        return [_rounded(v) for v in a]
    return a


def _same(a: object) -> str:
    return json.dumps(_rounded(a), sort_keys=True)  # NaN == NaN


@pytest.mark.slow  # three lockstep runs of 4-5 simulated seconds
def test_sweep_rows_and_verdicts_match_the_record(tmp_path: Path) -> None:
    out = tmp_path / "s.json"
    args = RECORD["command"].split()[1:] + ["--jobs", "1", "--no-progress", "--json", str(out)]
    assert main(args) == 0
    got = json.loads(out.read_text())
    rows = [{k: v for k, v in r.items() if k != "wall_s"} for r in got["runs"]]
    assert len(rows) == len(RECORD["runs"])
    for mine, want in zip(rows, RECORD["runs"], strict=True):
        moved = sorted(k for k in want if _same(mine.get(k)) != _same(want[k]))
        assert not moved, f"delay {want['delay_s']} s: {moved} differ from the record"
    for key in ("measured_max_stable_delay_s", "measured_bracket_s",
                "predicted_max_stable_delay_s"):
        assert _same(got[key]) == _same(RECORD[key])
