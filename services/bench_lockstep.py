"""``teleop bench lockstep``: the three services in lockstep, physics engine by engine.

One run, side by side: the lockstep runner of ``teleop sweep`` (:func:`services.lockstep.
run_lockstep`, default config: virtual operator, two-layer controller, simulated hand
grasping the default cylinder) with ``hand.sim.engine`` = ``python`` (the reference step) and
``compiled``; and the hand backend alone (``SimHand``, 40 Hz reads of 1 kHz physics with its
energy audit, as the hand service drives it).  Real-time factors are simulated seconds per
CPU second (best of ``repeats``; ``_wall`` beside them), ``*_over_python`` the ratios, and
``profile_share_*`` where the compiled run's CPU goes (cProfile's own time grouped by
package), so what dominates once the physics is fast is a figure, not a guess.
"""

from __future__ import annotations

import cProfile
import pstats
import time
from collections.abc import Callable

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


def bench_lockstep(sim_time_s: float = 10.0, repeats: int = 2) -> dict[str, float]:
    """Figures for ``teleop bench lockstep`` (see the module docstring)."""
    from services.lockstep import run_lockstep

    out: dict[str, float] = {"sim_time_s": sim_time_s}
    for eng in ("python", "compiled"):
        cfg = load_config(None, [f"hand.sim.engine={eng}"])
        run_lockstep(cfg, 0.2, seed=1)  # imports, the compiled engine's cache, tables
        cpu, wall = _best(lambda c=cfg: run_lockstep(c, sim_time_s, seed=1), sim_time_s,
                          repeats)
        out[f"{eng}_lockstep_realtime_factor"] = cpu
        out[f"{eng}_lockstep_realtime_factor_wall"] = wall
        cpu, wall = _best(lambda c=cfg: _simhand_run(c, sim_time_s), sim_time_s, repeats)
        out[f"{eng}_simhand_realtime_factor"] = cpu
        out[f"{eng}_simhand_realtime_factor_wall"] = wall
    for what in ("lockstep", "simhand"):
        out[f"compiled_{what}_over_python"] = (out[f"compiled_{what}_realtime_factor"]
                                               / out[f"python_{what}_realtime_factor"])
    out.update(_profile_shares(load_config(None, ["hand.sim.engine=compiled"]), sim_time_s))
    return out
