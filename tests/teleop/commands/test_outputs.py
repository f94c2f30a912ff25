"""Output files are tried before a command's work, whatever the command.

``teleop budget --seconds 600 --json X`` ran its ten minutes and only then found X
unwritable (and ``teleop diagnose``, ``faults`` and ``watch`` did the same with theirs): the
results were computed and lost.  Every option naming a file a command writes is registered
(:func:`teleop.commands.common.add_output_option`) and :func:`teleop.cli.main` tries each
before the command runs: one line, exit status 2, nothing started.
"""

from __future__ import annotations

import argparse
import importlib
import subprocess
import sys
import time
from pathlib import Path

import pytest

from teleop import cli

#: (command, argv after it with {bad} where an output file goes) for every registered output
CASES: tuple[tuple[str, str], ...] = (
    ("budget", "--seconds 600 --json {bad}"),
    ("diagnose", "rec.csv --json {bad}"),
    ("diagnose", "rec.csv --plot {bad}"),
    ("diagnose", "rec.csv --model finger --write-params {bad}"),
    ("faults", "--json {bad}"),
    ("watch", "--duration 600 --json {bad}"),
    ("sweep", "--json {bad}"),
    ("sweep", "--plot {bad}"),
    ("sweep", "--rerun {bad}"),
    ("sim", "grasp --out {bad}"),
    ("sim", "grasp --json {bad}"),
    ("bench", "lockstep --json {bad}"),
    ("hand-emulator", "--json {bad}"),
    ("grasps", "rundir --json {bad}"),
    ("certs", "certdir --json {bad}"),
)


def _subcommands() -> dict[str, argparse.ArgumentParser]:
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def _bad(tmp_path: Path) -> Path:
    """A path no one can write: its parent is a regular file."""
    (tmp_path / "a-file").write_text("")
    return tmp_path / "a-file" / "out"


def test_every_option_that_writes_a_file_is_checked_before_the_work() -> None:
    """A new ``--something PATH`` whose help says it writes must be registered too (the
    ``--record DIR`` of up and run is a directory of per-role files: checked by each)."""
    missing = []
    for name, sp in _subcommands().items():
        registered = {dest for dest, _ in sp.get_default("output_paths") or ()}
        for a in sp._actions:
            text = (a.help or "").lower()
            writes = text.startswith(("write", "log every")) and a.option_strings
            if writes and a.dest not in registered and a.dest != "record":
                missing.append(f"{name} {a.option_strings[0]}")
    assert not missing, missing
    covered = {(c, a.split("{bad}")[0].split()[-1]) for c, a in CASES}
    for name, sp in _subcommands().items():
        flags = {next(x.option_strings[-1] for x in sp._actions if x.dest == dest)
                 for dest, _ in sp.get_default("output_paths") or ()}
        assert {(name, f) for f in flags} <= covered, (name, flags)


@pytest.mark.parametrize(("command", "argv"), CASES, ids=[f"{c} {a}" for c, a in CASES])
def test_an_unwritable_output_stops_the_command_before_it_runs(
        command: str, argv: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    ran: list[str] = []
    module = importlib.import_module(f"teleop.commands.{command.replace('-', '_')}")
    monkeypatch.setattr(module, "run", lambda args: ran.append(command) or 0)
    bad = _bad(tmp_path)
    code = cli.main([command, *argv.format(bad=bad).split()])
    err = capsys.readouterr().err
    assert code == 2 and not ran, (code, ran, err)
    assert err.count("\n") == 1 and str(bad) in err and "cannot write" in err, err


def test_a_writable_output_lets_the_command_run(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    ran: list[str] = []
    module = importlib.import_module("teleop.commands.budget")
    monkeypatch.setattr(module, "run", lambda args: ran.append(args.json_path) or 0)
    out = tmp_path / "new" / "budget.json"
    assert cli.main(["budget", "--json", str(out)]) == 0 and ran == [str(out)]
    assert cli.main(["budget", "--json", "-"]) == 0  # stdout always passes


@pytest.mark.parametrize("argv", [
    "budget --seconds 600 --json {bad}",  # ten minutes of lockstep if it ran first
    "run master --record {bad} --set session.name=outputs-test",  # waits for peers forever
], ids=["budget", "run --record"])
def test_the_installed_command_fails_in_one_line_at_once(argv: str, tmp_path: Path) -> None:
    bad = _bad(tmp_path)
    t0 = time.monotonic()
    proc = subprocess.run([sys.executable, "-m", "teleop.cli", *argv.format(bad=bad).split()],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1 and "cannot write" in proc.stderr, proc.stderr
    assert time.monotonic() - t0 < 30.0
