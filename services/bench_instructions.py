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
from pathlib import Path

from teleop.errors import UserInputError

#: the C function callgrind collects in: the script runs the measured lockstep inside it
TOGGLE = "functools_reduce"

#: argv: engine, simulated seconds
_SCRIPT = """
import functools, sys
from services.lockstep import run_lockstep
from teleop.config import load_config
cfg = load_config(None, ["hand.sim.engine=" + sys.argv[1]])
run_lockstep(cfg, float(sys.argv[2]), seed=1)
functools.reduce(lambda a, b: run_lockstep(cfg, float(sys.argv[2]), seed=1), [0, 0])
"""

_COLLECTED = re.compile(r"Collected\s*:\s*(\d+)")


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
    valgrind = valgrind_path()
    env = {**os.environ, "PYTHONPATH": str(tree)}
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [valgrind, "--tool=callgrind", f"--toggle-collect={TOGGLE}",
               f"--callgrind-out-file={Path(tmp) / 'callgrind.out'}", sys.executable, "-c",
               _SCRIPT, engine, repr(float(sim_s))]
        done = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"callgrind run in {tree} failed (exit {done.returncode}):\n"
                           + done.stderr[-2000:])
    n = collected(done.stderr)
    if n == 0:
        raise RuntimeError(f"callgrind counted nothing in {TOGGLE}: this Python's library has "
                           "no symbol of that name, so the timed run cannot be isolated")
    return n


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
