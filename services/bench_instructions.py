"""Fixed-work figures for ``teleop bench lockstep --instructions``: instructions, not seconds.

The lockstep's real-time factor moves about 10 % between runs on this VM (other load, CPU
frequency, the VM's stalls), so a ratio near a goal can land either side of it from one run to
the next.  The number of machine instructions a run executes does not depend on the load: one
lockstep run of ``sim_s`` simulated seconds (default config, seed 1) is run under valgrind's
callgrind, which counts only what executes inside ``functools.reduce``
(``--toggle-collect=functools_reduce``): the script calls the measured run through it, so
start-up, imports and a first, identical warm-up run are not counted.  The warm-up is the same
run so that every compiled kernel the measured run calls is loaded (or compiled) before it: a
kernel first called late in a run would otherwise be loaded inside the count (a 1 s count
once read 764 M instead of 670 M so).  Counts repeat within about 0.1 %.

Instructions are not time: the two trees' code need not run at the same instructions per
cycle, so the ratio of counts is a steadier figure beside the timed ratio, not a replacement.
Needs ``valgrind`` on the PATH; the first run in a tree compiles numba's kernels for
valgrind's emulated CPU (several minutes, then cached beside the native ones).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

from teleop.errors import UserInputError

#: the C function callgrind collects in: the script runs the measured lockstep inside it
TOGGLE = "functools_reduce"

#: argv: engine, then the simulated seconds of each measured run (one warm-up run as long as
#: the longest first; each measured run inside its own ``functools.reduce``)
_SCRIPT = """
import functools, sys
from services.lockstep import run_lockstep
from teleop.config import load_config
cfg = load_config(None, ["hand.sim.engine=" + sys.argv[1]])
runs = [float(a) for a in sys.argv[2:]]
run_lockstep(cfg, max(runs), seed=1)
for s in runs:
    functools.reduce(lambda a, b, s=s: run_lockstep(cfg, s, seed=1), [0, 0])
"""
_COLLECTED = re.compile(r"Collected\s*:\s*(\d+)")
_TOTALS = re.compile(r"^totals:\s*(\d+)", re.M)


def valgrind_path() -> str:
    """The ``valgrind`` executable, or UserInputError naming what is missing."""
    found = shutil.which("valgrind")
    if found is None:
        raise UserInputError("--instructions: valgrind not found on the PATH (install it, e.g. "
                             "`apt-get install valgrind`, or leave --instructions out)")
    return found


def collected(log: str) -> int:
    """The instruction count in callgrind's summary ``log`` (its stderr)."""
    m = _COLLECTED.search(log)
    if m is None:
        raise RuntimeError("callgrind printed no 'Collected' count:\n" + log[-2000:])
    return int(m.group(1))


def count_instructions(tree: Path, engine: str, sim_s: float) -> int:
    """Instructions of one ``sim_s`` s lockstep run of the source ``tree`` on ``engine``."""
    return count_instructions_each(tree, engine, (sim_s,))[0]


def count_instructions_each(tree: Path, engine: str, sims_s: Sequence[float]) -> list[int]:
    """Instructions of each of the lockstep runs of ``sims_s`` simulated seconds, one after
    another in one process under callgrind (one start-up and warm-up for all): callgrind
    dumps its count on every exit from the measured runs' ``functools.reduce``
    (``--dump-after``), the ``k``-th dump holding the ``k``-th run's."""
    valgrind = valgrind_path()
    env = {**os.environ, "PYTHONPATH": str(tree)}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "callgrind.out"
        cmd = [valgrind, "--tool=callgrind", f"--toggle-collect={TOGGLE}",
               f"--dump-after={TOGGLE}", f"--callgrind-out-file={out}", sys.executable, "-c",
               _SCRIPT, engine, *(repr(float(s)) for s in sims_s)]
        done = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True)
        if done.returncode != 0:
            raise RuntimeError(f"callgrind run in {tree} failed (exit {done.returncode}):\n"
                               + done.stderr[-2000:])
        counts = [dumped(Path(f"{out}.{k}")) for k in range(1, len(sims_s) + 1)]
    if collected(done.stderr) == 0 or 0 in counts:
        raise RuntimeError(f"callgrind counted nothing in {TOGGLE}: this Python's library has "
                           "no symbol of that name, so the timed run cannot be isolated")
    return counts


def dumped(path: Path) -> int:
    """The instruction count of one callgrind dump file (its ``totals:`` line)."""
    m = _TOTALS.search(path.read_text()) if path.is_file() else None
    if m is None:
        raise RuntimeError(f"callgrind wrote no count in {path.name}")
    return int(m.group(1))


def instruction_figures(this_tree: Path, reference: Path | None,
                        sim_s: float = 1.0) -> dict[str, float]:
    """Instructions per simulated second of this tree (compiled engine) and of ``reference``
    (Python engine: the pair of issue 16's lockstep goal), and their ratio (reference over
    this tree: how many times fewer this tree executes)."""
    out: dict[str, float] = {"instructions_sim_time_s": sim_s}
    mine = count_instructions(this_tree, "compiled", sim_s) / sim_s
    out["compiled_lockstep_instructions_per_sim_s"] = mine
    if reference is not None:
        ref = count_instructions(reference, "python", sim_s) / sim_s
        out["reference_python_lockstep_instructions_per_sim_s"] = ref
        out["compiled_lockstep_over_reference_python_instructions"] = ref / mine
    return out
