"""``teleop bench sim``'s scenarios on the compiled engine, the controller compiled beside it.

The same 1 kHz controller as :func:`sim.bench._finger_run` / :func:`sim.bench._hand_run` (a
0.5 Hz sine of the joint set-point, a proportional correction on the measured proximal angle
for the finger), stepping the compiled model (:func:`sim.compiled_step.advance_in`, the step
the equivalence tests hold to the Python reference, with one work array as the runs use it).
``tests/sim/test_compiled_engine.py`` checks that these loops follow the Python benchmark's
trajectory.

Numba's disk cache keys each function on its own file only, not on the kernels it
inlines; :mod:`sim.compiled_cache` drops the cache of every compiled module when any of
their sources changes, so an edit of the step or of the array layouts recompiles this
file's functions too.
"""

from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

from sim.compiled import hand_arrays, pack_effects, pack_object, pack_params, state_array
from sim.compiled_kernel import X_PHI
from sim.compiled_runs import preshape_step
from sim.compiled_step import advance_in, work_array
from sim.contact import ContactObject
from sim.finger import default_finger_params, initial_finger_state
from sim.hand import default_hand_params
from sim.params import JOINT_RATIO
from teleop.effects import EffectSet


@njit(cache=True)
def finger_loop(steps: int, x: np.ndarray, k: np.ndarray, dsegs: np.ndarray, o: np.ndarray,
                e: np.ndarray, dt: float) -> None:
    """The finger benchmark's controller and physics, ``steps`` ticks, in place on ``x``."""
    w = 2.0 * math.pi * 0.5
    c = np.array([0.0, 0.0, 0.0, 0.0, 1.0])
    work = work_array(k)
    for i in range(steps):
        sp = 0.7 - 0.7 * math.cos(w * i * dt)
        c[1] = JOINT_RATIO * (sp + 0.2 * (sp - x[X_PHI]))
        advance_in(x, c, k, dsegs, o, e, dt, -1.0, work)


@njit(cache=True)
def hand_loop(steps: int, xs: np.ndarray, pre: np.ndarray, hp: np.ndarray, k: np.ndarray,
              dsegs: np.ndarray, o: np.ndarray, e: np.ndarray, dt: float) -> None:
    """The hand benchmark (three fingers on one set-point, preshape at 0.3 rad)."""
    w = 2.0 * math.pi * 0.5
    c = np.array([0.0, 0.0, 0.0, 0.0, 1.0])
    work = work_array(k)
    for i in range(steps):
        c[1] = JOINT_RATIO * (0.7 - 0.7 * math.cos(w * i * dt))
        for f in range(xs.shape[0]):
            advance_in(xs[f], c, k, dsegs, o, e, dt, -1.0, work)
        pre[1], pre[2] = preshape_step(pre[1], pre[2], 0.3, hp, dt)
        pre[0] = pre[0] + dt


def finger_arrays() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(x, k, dsegs, o, e) of the finger benchmark's start: default finger, cylinder."""
    p = default_finger_params()
    k, dsegs = pack_params(p)
    return (state_array(initial_finger_state(p)), k, dsegs,
            pack_object(ContactObject(kind="cylinder")), pack_effects(EffectSet()))


def compiled_finger_run(sim_time_s: float) -> tuple[float, float]:
    """(wall, CPU) seconds for ``sim_time_s`` of the finger benchmark, compiled."""
    x, k, dsegs, o, e = finger_arrays()
    w0, c0 = time.perf_counter(), time.process_time()
    finger_loop(int(sim_time_s / 1e-3), x, k, dsegs, o, e, 1e-3)
    return time.perf_counter() - w0, time.process_time() - c0


def compiled_hand_run(sim_time_s: float) -> tuple[float, float]:
    """(wall, CPU) seconds for ``sim_time_s`` of the hand benchmark, compiled."""
    x, k, dsegs, o, e = finger_arrays()
    xs = np.array([x, x, x])
    pre = np.zeros(3)
    hp = hand_arrays(default_hand_params())
    w0, c0 = time.perf_counter(), time.process_time()
    hand_loop(int(sim_time_s / 1e-3), xs, pre, hp, k, dsegs, o, e, 1e-3)
    return time.perf_counter() - w0, time.process_time() - c0
