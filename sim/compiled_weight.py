"""``sim.finger.weight_equilibrium`` compiled: the hung-weight release run until still.

Table 4.2's weight test, the ``weight`` experiment's summary and the static finger diagnosis
find each equilibrium by running the detached finger for up to 30 s; the same loop and stop
rule (speeds below 1e-6 rad/s after 100 steps) as the reference, compiled.

Numba's disk cache keys each function on its own file only, not on the kernels it
inlines; :mod:`sim.compiled_cache` drops the cache of every compiled module when any of
their sources changes, so an edit of the step or of the array layouts recompiles this
file's functions too.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from sim.compiled_kernel import X_FLEX, X_PHI, X_VPHI
from sim.compiled_step import advance_in, work_array

if TYPE_CHECKING:
    from sim.params import FingerParams
    from teleop.effects import EffectSet


@njit(cache=True)
def release_until_still(x: np.ndarray, k: np.ndarray, dsegs: np.ndarray, o: np.ndarray,
                        e: np.ndarray, force_n: float, dt: float, steps: int) -> None:
    """Step ``x`` in place with ``force_n`` on the detached tendon until it is still."""
    hold = np.array([0.0, 0.0, 0.0, 0.0, 1.0])  # sim.motor.HOLD_ZERO, always in force here
    n = (x.shape[0] - X_FLEX) // 2
    w = work_array(k)
    for step in range(steps):
        advance_in(x, hold, k, dsegs, o, e, dt, force_n, w)
        if step > 100 and abs(x[X_VPHI]) < 1e-6:
            still = True
            for i in range(n):
                if abs(x[X_FLEX + n + i]) >= 1e-6:
                    still = False
                    break
            if still:
                break


def compiled_weight_equilibrium(params: FingerParams, force_n: float, dt_s: float,
                                max_time_s: float, effects: EffectSet) -> tuple[float, float]:
    """(proximal, distal rad) as ``sim.finger.weight_equilibrium`` returns them."""
    from sim import compiled as cp
    from sim.contact import ContactObject
    from sim.state import initial_finger_state

    x = cp.state_array(initial_finger_state(params))
    k, dsegs = cp.pack_params(params)
    release_until_still(x, k, dsegs, cp.pack_object(ContactObject()), cp.pack_effects(effects),
                        float(max(force_n, 0.0)), float(dt_s), int(max_time_s / dt_s))
    n = (x.size - X_FLEX) // 2
    return float(x[X_PHI]), sum(x[X_FLEX:X_FLEX + n].tolist())
