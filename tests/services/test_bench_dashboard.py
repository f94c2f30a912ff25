"""``teleop bench dashboard``: its inputs (the measurement itself runs ``teleop up`` for
20 s per tree; the same lateness is held on every CI run by
``tests/services/test_up.py::test_recordings_show_the_grasp_and_the_energy_balance``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from teleop.cli import main


def test_a_reference_that_is_no_source_tree_is_one_line_exit_2(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "dashboard", "--reference", str(tmp_path)]) == 2
    assert main(["bench", "dashboard", "--repeats", "0"]) == 2
    assert main(["bench", "loop", "--repeats", "2"]) == 2
    err = [x for x in capsys.readouterr().err.splitlines() if x.strip()]
    assert len(err) == 3, err
    assert "not a source tree" in err[0] and "--repeats" in err[1] and "--repeats" in err[2]
