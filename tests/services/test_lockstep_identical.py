"""Speed never buys a different answer: lockstep runs match, bit for bit, the digests recorded
from the implementation before the lockstep was made faster (issue 16).

Each scenario's every series (``LockstepResult`` field) is hashed from its float64 bytes
(:mod:`lockstep_digest`); a mismatch names the fields that moved.  Record again only for an
intended behaviour change (``python tests/services/lockstep_digest.py >
tests/services/data/lockstep_digests.json``) and say so in the commit.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from lockstep_digest import SCENARIOS, run_scenario

RECORD = json.loads((Path(__file__).parent / "data" / "lockstep_digests.json").read_text())


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_lockstep_run_is_bit_identical_to_the_record(name: str) -> None:
    got, want = run_scenario(name), RECORD[name]
    moved = sorted(k for k in want if got.get(k) != want[k])
    assert not moved, f"{name}: fields differ from the recorded run: {moved}"
    assert set(got) == set(want)
