"""``teleop bench sim``: how much faster than real time the finger and hand models run.

Scenario: a 1 kHz position controller (a 0.5 Hz sine of the joint set-point between 0 and
1.4 rad) drives one finger against the default cylinder (so contact is part of the run), with
the physics stepped once per controller tick (dt = 1 ms).  The hand figure runs the same
controller on all three fingers plus the preshape joint through :func:`sim.hand.hand_step`.

Both engines run in the same call, side by side: ``python_*`` is the reference step called
from a Python controller loop, ``compiled_*`` the compiled engine (:mod:`sim.compiled_step`,
the step held to the reference by ``tests/sim/test_compiled_engine.py``) with the same
controller compiled beside it (:mod:`sim.bench_compiled`), and ``compiled_per_call_*`` the
compiled step called once a tick from Python (the price of the interpreter between steps).
``*_over_python`` are the ratios.
"""

from __future__ import annotations

import math
import time

from sim.finger import (
    NO_EFFECTS,
    ContactObject,
    MotorCommand,
    default_finger_params,
    finger_step,
    initial_finger_state,
)
from sim.hand import HandMotorCommand, default_hand_params, hand_step, initial_hand_state
from sim.params import JOINT_RATIO


def _finger_run(sim_time_s: float) -> tuple[float, float]:
    """(wall, CPU) seconds for ``sim_time_s`` of one finger under a 1 kHz controller."""
    p = default_finger_params()
    obj = ContactObject(kind="cylinder")
    st = initial_finger_state(p)
    dt = 1e-3
    steps = int(sim_time_s / dt)
    w = 2.0 * math.pi * 0.5
    w0, c0 = time.perf_counter(), time.process_time()
    for k in range(steps):
        sp = 0.7 - 0.7 * math.cos(w * k * dt)
        # proportional correction on the measured proximal angle (the controller's work)
        goal = JOINT_RATIO * (sp + 0.2 * (sp - st.prox_rad))
        st = finger_step(st, MotorCommand("position", goal), p, obj, NO_EFFECTS, dt)
    return time.perf_counter() - w0, time.process_time() - c0


def _hand_run(sim_time_s: float) -> tuple[float, float]:
    """(wall, CPU) seconds for ``sim_time_s`` of the whole hand under a 1 kHz controller."""
    hp = default_hand_params()
    obj = ContactObject(kind="cylinder")
    st = initial_hand_state(hp)
    dt = 1e-3
    steps = int(sim_time_s / dt)
    w = 2.0 * math.pi * 0.5
    w0, c0 = time.perf_counter(), time.process_time()
    for k in range(steps):
        sp = 0.7 - 0.7 * math.cos(w * k * dt)
        m = MotorCommand("position", JOINT_RATIO * sp)
        cmd = HandMotorCommand((m, m, m), 0.3)
        st = hand_step(st, cmd, hp, obj, NO_EFFECTS, dt)
    return time.perf_counter() - w0, time.process_time() - c0


def _finger_per_call_run(sim_time_s: float) -> tuple[float, float]:
    """:func:`_finger_run` with the compiled step called from Python once a tick."""
    from sim.compiled import compiled_finger_step

    p = default_finger_params()
    obj = ContactObject(kind="cylinder")
    st = initial_finger_state(p)
    dt = 1e-3
    w = 2.0 * math.pi * 0.5
    w0, c0 = time.perf_counter(), time.process_time()
    for k in range(int(sim_time_s / dt)):
        sp = 0.7 - 0.7 * math.cos(w * k * dt)
        goal = JOINT_RATIO * (sp + 0.2 * (sp - st.prox_rad))
        st = compiled_finger_step(st, MotorCommand("position", goal), p, obj, NO_EFFECTS, dt)
    return time.perf_counter() - w0, time.process_time() - c0


def _figures(prefix: str, runs: list[tuple[float, float]], sim_s: float) -> dict[str, float]:
    cpu = min(c for _, c in runs)
    wall = min(w for w, _ in runs)
    return {f"{prefix}_realtime_factor": sim_s / cpu,
            f"{prefix}_realtime_factor_wall": sim_s / wall,
            f"{prefix}_step_us": cpu / (sim_s * 1000.0) * 1e6}


def bench_sim(sim_time_s: float = 10.0, repeats: int = 3) -> dict[str, float]:
    """Figures for ``teleop bench sim``: real-time factors (best of ``repeats``), the Python
    reference and the compiled engine side by side, and their ratios.

    ``*_realtime_factor`` use the process's CPU time (robust to other load on the machine);
    ``*_wall`` the wall clock.  The compiled runs are 20 times longer (timer resolution).
    """
    from sim.bench_compiled import compiled_finger_run, compiled_hand_run
    from sim.compiled import warm_up

    t0 = time.perf_counter()
    warm_up()
    compiled_finger_run(0.01)  # the benchmark's own loops: compiled or loaded, not timed
    compiled_hand_run(0.01)
    warm = time.perf_counter() - t0
    long_s = 20.0 * sim_time_s
    out: dict[str, float] = {"sim_time_s": sim_time_s, "controller_rate_hz": 1000.0,
                             "physics_dt_s": 1e-3, "compiled_warm_up_s": warm}
    out.update(_figures("python_finger", [_finger_run(sim_time_s) for _ in range(repeats)],
                        sim_time_s))
    out.update(_figures("python_hand", [_hand_run(sim_time_s / 2.0) for _ in range(repeats)],
                        sim_time_s / 2.0))
    out.update(_figures("compiled_finger", [compiled_finger_run(long_s)
                                            for _ in range(repeats)], long_s))
    out.update(_figures("compiled_hand", [compiled_hand_run(long_s / 2.0)
                                          for _ in range(repeats)], long_s / 2.0))
    out.update(_figures("compiled_per_call_finger",
                        [_finger_per_call_run(sim_time_s) for _ in range(repeats)], sim_time_s))
    for what in ("finger", "hand", "per_call_finger"):
        base = "hand" if what == "hand" else "finger"
        out[f"compiled_{what}_over_python"] = (out[f"compiled_{what}_realtime_factor"]
                                               / out[f"python_{base}_realtime_factor"])
    # the headline keys of earlier versions: now the compiled engine's
    out["realtime_factor"] = out["finger_realtime_factor"] = out["compiled_finger_realtime_factor"]
    out["hand_realtime_factor"] = out["compiled_hand_realtime_factor"]
    return out
