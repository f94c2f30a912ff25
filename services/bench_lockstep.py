"""``teleop bench lockstep``: the three services in lockstep, physics engine by engine.

One run, side by side: the lockstep runner of ``teleop sweep`` (:func:`services.lockstep.
run_lockstep`, default config: virtual operator, two-layer controller, simulated hand
grasping the default cylinder) with ``hand.sim.engine`` = ``python`` (the reference step) and
``compiled``; and the hand backend alone (``SimHand``, 40 Hz reads of 1 kHz physics with its
energy audit, as the hand service drives it).  Real-time factors are simulated seconds per
CPU second (best of ``repeats``; ``_wall`` beside them), ``*_over_python`` the ratios, and
``profile_share_*`` where the compiled run's CPU goes (cProfile's own time grouped by
package), so what dominates once the physics is fast is a figure, not a guess.

``reference`` (``teleop bench lockstep --reference DIR``): a source tree of an earlier
implementation (``mkdir /tmp/ref && git archive dc373eb | tar -x -C /tmp/ref``) whose
lockstep runs the same seconds on both engines in a subprocess, alternating with this tree's
runs in the same repetitions, so ``compiled_lockstep_over_reference_python`` is this tree
against the one before it, measured side by side (``reference_*`` its own figures).

``--instructions``: the same comparison in machine instructions counted by callgrind (this
tree's compiled engine, the reference's Python engine), a figure that does not move with the
machine's load (:mod:`services.bench_instructions`).
"""

from __future__ import annotations

import cProfile
import json
import os
import pstats
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from teleop.config import TeleopConfig, load_config

#: package prefix (path fragment) -> key of its profile share
AREAS: tuple[tuple[str, str], ...] = (
    ("/sim/", "physics_and_operator"), ("/teleop/transport/", "transport"),
    ("/teleop/control/", "control"), ("/services/", "services"),
    ("/teleop/", "teleop_other"),
)


def _best(run: Callable[[], object], sim_s: float, repeats: int) -> tuple[float, float]:
    """(CPU, wall) real-time factors, best of ``repeats``."""
    cpu = wall = 0.0
    for _ in range(repeats):
        c0, w0 = time.process_time(), time.perf_counter()
        run()
        cpu = max(cpu, sim_s / (time.process_time() - c0))
        wall = max(wall, sim_s / (time.perf_counter() - w0))
    return cpu, wall


def _simhand_run(cfg: TeleopConfig, sim_s: float) -> None:
    from sim.sim_hand import SimHand
    from teleop.messages import HandCommand, HandMode, Header

    hand = SimHand(cfg.hand, seed=0)
    hand.start()
    hand.apply(HandCommand(Header(1, 0.0, 0.0), (1.2, 1.2, 1.0), 0.3, HandMode.POSITION,
                           (0.0, 0.0, 0.0)))
    for k in range(1, int(sim_s * 40.0) + 1):
        hand.read(k / 40.0)


def _profile_shares(cfg: TeleopConfig, sim_s: float) -> dict[str, float]:
    from services.lockstep import run_lockstep

    prof = cProfile.Profile()
    prof.enable()
    run_lockstep(cfg, sim_s, seed=1)
    prof.disable()
    stats = pstats.Stats(prof).stats  # type: ignore[attr-defined]
    total = sum(v[2] for v in stats.values()) or 1.0
    shares = {f"profile_share_{key}": 0.0 for _, key in AREAS}
    shares["profile_share_library_and_builtins"] = 0.0
    for (path, _, _), v in stats.items():
        key = next((k for frag, k in AREAS if frag in path), "library_and_builtins")
        shares[f"profile_share_{key}"] += v[2] / total
    return shares


#: one timed lockstep run in a reference tree (argv: engine, seconds; prints CPU and wall s)
_REFERENCE_RUN = """
import json, sys, time
from services.lockstep import run_lockstep
from teleop.config import load_config
cfg = load_config(None, ["hand.sim.engine=" + sys.argv[1]])
run_lockstep(cfg, 0.2, seed=1)
c0, w0 = time.process_time(), time.perf_counter()
run_lockstep(cfg, float(sys.argv[2]), seed=1)
print(json.dumps([time.process_time() - c0, time.perf_counter() - w0]))
"""


def _reference_run(tree: Path, engine: str, sim_s: float) -> tuple[float, float]:
    """(CPU, wall) real-time factors of one lockstep run of the source tree ``tree``."""
    env = {**os.environ, "PYTHONPATH": str(tree)}
    done = subprocess.run([sys.executable, "-c", _REFERENCE_RUN, engine, str(sim_s)],
                          cwd=tree, env=env, capture_output=True, text=True, check=True)
    cpu_s, wall_s = json.loads(done.stdout.strip().splitlines()[-1])
    return sim_s / cpu_s, sim_s / wall_s


def check_reference(reference: str) -> Path:
    """``reference`` as a path, or UserInputError if it is no source tree of this project."""
    tree = Path(reference).resolve()
    if not (tree / "services" / "lockstep.py").is_file():
        from teleop.errors import UserInputError

        raise UserInputError(f"--reference {reference}: not a source tree of this project "
                             "(no services/lockstep.py)")
    return tree


def bench_lockstep(sim_time_s: float = 10.0, repeats: int = 2,
                   reference: str | None = None,
                   instructions: bool = False) -> dict[str, float]:
    """Figures for ``teleop bench lockstep`` (see the module docstring); ``instructions``:
    the fixed-work figures of :mod:`services.bench_instructions` too (valgrind)."""
    from services.lockstep import run_lockstep

    tree = check_reference(reference) if reference is not None else None
    if instructions:
        from services.bench_instructions import valgrind_path

        valgrind_path()  # before minutes of timing: a missing valgrind is a bad input
    out: dict[str, float] = {"sim_time_s": sim_time_s}
    for eng in ("python", "compiled"):
        cfg = load_config(None, [f"hand.sim.engine={eng}"])
        run_lockstep(cfg, 0.2, seed=1)  # imports, the compiled engine's cache, tables
        cpu = wall = ref_cpu = ref_wall = 0.0
        for _ in range(repeats):  # this tree and the reference alternate: the same load
            c, w = _best(lambda c=cfg: run_lockstep(c, sim_time_s, seed=1), sim_time_s, 1)
            cpu, wall = max(cpu, c), max(wall, w)
            if tree is not None:
                c, w = _reference_run(tree, eng, sim_time_s)
                ref_cpu, ref_wall = max(ref_cpu, c), max(ref_wall, w)
        out[f"{eng}_lockstep_realtime_factor"] = cpu
        out[f"{eng}_lockstep_realtime_factor_wall"] = wall
        if tree is not None:
            out[f"reference_{eng}_lockstep_realtime_factor"] = ref_cpu
            out[f"reference_{eng}_lockstep_realtime_factor_wall"] = ref_wall
        cpu, wall = _best(lambda c=cfg: _simhand_run(c, sim_time_s), sim_time_s, repeats)
        out[f"{eng}_simhand_realtime_factor"] = cpu
        out[f"{eng}_simhand_realtime_factor_wall"] = wall
    for what in ("lockstep", "simhand"):
        out[f"compiled_{what}_over_python"] = (out[f"compiled_{what}_realtime_factor"]
                                               / out[f"python_{what}_realtime_factor"])
    if tree is not None:
        for eng in ("python", "compiled"):
            for ref in ("python", "compiled"):
                out[f"{eng}_lockstep_over_reference_{ref}"] = (
                    out[f"{eng}_lockstep_realtime_factor"]
                    / out[f"reference_{ref}_lockstep_realtime_factor"])
    out.update(_profile_shares(load_config(None, ["hand.sim.engine=compiled"]), sim_time_s))
    if instructions:
        from services.bench_instructions import instruction_figures

        out.update(instruction_figures(Path(__file__).resolve().parents[1], tree))
    return out
