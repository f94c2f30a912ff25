"""``teleop up`` children that fail or overrun are one-line device errors (the live sweep's
points, the dashboard benchmark's runs)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from teleop.analysis.up_child import run_up
from teleop.errors import DeviceError


def _tree(tmp_path: Path, body: str) -> Path:
    """A stand-in source tree whose ``python -m teleop.cli`` runs ``body``."""
    pkg = tmp_path / "tree" / "teleop"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "cli.py").write_text(body)
    return tmp_path / "tree"


def test_a_child_that_fails_is_named_with_its_last_line(tmp_path: Path) -> None:
    tree = _tree(tmp_path, "import sys\nprint('starting')\n"
                 "print('first', file=sys.stderr)\nprint('the last words', file=sys.stderr)\n"
                 "sys.exit(3)\n")
    with pytest.raises(DeviceError) as err:
        run_up(["--duration", "1"], timeout_s=60, what="bench dashboard", tree=tree)
    msg = str(err.value)
    assert msg == (f"bench dashboard: teleop up (tree {tree}) exited with status 3: "
                   "the last words")


def test_a_child_that_overruns_is_stopped_and_named(tmp_path: Path) -> None:
    tree = _tree(tmp_path, "import time\ntime.sleep(30)\n")
    t0 = time.monotonic()
    with pytest.raises(DeviceError, match="^live sweep point: teleop up did not finish "
                       "within 1 s$"):
        run_up([], timeout_s=1.0, what="live sweep point", tree=tree)
    assert time.monotonic() - t0 < 10.0


def test_the_real_command_with_a_bad_key_is_a_device_error_naming_it() -> None:
    with pytest.raises(DeviceError, match="exited with status 2: teleop up: error: --set: "
                       "nope is not a known key"):
        run_up(["--set", "nope=1"], timeout_s=60, what="t")


def test_a_child_that_succeeds_returns_its_output(tmp_path: Path) -> None:
    tree = _tree(tmp_path, "import sys\nprint('args', sys.argv[1:])\n")
    proc = run_up(["--duration", "2"], timeout_s=60, what="t", tree=tree)
    assert proc.stdout.strip() == "args ['up', '--duration', '2']"
