"""``sim.finger_dynamic.simulate_dynamic`` in one compiled call (the diagnosis's inner loop).

The fit simulates the whole recording for every trial of its parameters, so every recorded
row (1 kHz) paid the interpreter.  Here the rows' commands, the delay line (``dead_time`` and
the driver's delay, as ``sim.finger._step`` keeps it), the segments that restart settled after
an excluded stretch, and the physics all run compiled; the result is the reference's to
rounding (``tests/sim/test_compiled_engine.py``).

Each row's steps run in one inlined loop (:func:`_run`, the step :data:`_advance` inlined
into it): the same operations in the same order as a call per step.

Numba's disk cache keys each function on its own file only, not on the kernels it
inlines; :mod:`sim.compiled_cache` drops the cache of every compiled module when any of
their sources changes, so an edit of the step or of the array layouts recompiles this
file's functions too.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from sim.compiled_kernel import K_UPN, X_PHI, X_REF, X_T, X_TEN, X_TH, X_VM
from sim.compiled_step import advance_in, work_array

#: the step, inlined (numba IR) into :func:`_run`'s loop, itself inlined into
#: :func:`simulate_rows` once per row (it was called twice a row, the step once a simulated
#: millisecond with nine array arguments): a 60 s run at 1 kHz 33 -> 24 ms, the same floats.
#: A copy of its own, not cached (the function's cache entry is :func:`advance_in`'s), so
#: only this loop pays the larger compile (about 2 s, once)
_advance = njit(inline="always")(advance_in.py_func)

if TYPE_CHECKING:
    from sim.finger_dynamic import DynamicData
    from sim.motor import MotorCommand
    from sim.params import FingerParams
    from teleop.effects import EffectSet

_HOLD = np.array([0.0, 0.0, 0.0, 0.0, 1.0])  # sim.motor.HOLD_ZERO


@njit(cache=True, inline="always")
def _run(x: np.ndarray, first: np.ndarray, then: np.ndarray, split: int, steps: int,
         dt: float, k: np.ndarray, dsegs: np.ndarray, o: np.ndarray, e: np.ndarray,
         delay: float, line: np.ndarray, due: np.ndarray, queued: np.ndarray,
         ends: np.ndarray, w: np.ndarray) -> None:
    """``steps`` steps, the first ``split`` under command ``first``, the rest under ``then``
    (``w``: the step's work array).  Delay line: ``line`` = [active (5), last (5), has
    last]; pending commands ``queued[j]`` due at ``due[j]`` for j in ``ends`` = [head,
    tail]."""
    for s in range(steps):
        cmd = first if s < split else then
        if delay <= 0.0:
            line[0:5] = cmd
        else:
            t = x[X_T]
            same = line[10] != 0.0
            for j in range(5):
                if line[5 + j] != cmd[j]:
                    same = False
            if not same:
                due[ends[1]] = t + delay
                queued[ends[1], :] = cmd
                ends[1] += 1
            while ends[0] < ends[1] and due[ends[0]] <= t + 1e-12:
                line[0:5] = queued[ends[0]]
                ends[0] += 1
        line[5:10] = cmd
        line[10] = 1.0
        _advance(x, line[0:5], k, dsegs, o, e, dt, -1.0, w)


@njit(cache=True)
def _hold(x: np.ndarray, settle: np.ndarray, goal: float, effort: float, offset: float,
          per_unit: float, steps: int, dt: float, k: np.ndarray, dsegs: np.ndarray,
          o: np.ndarray, e: np.ndarray, line: np.ndarray, w: np.ndarray) -> None:
    """The finger at the measured motor angle (``finger_dynamic._settled``): the shaft held
    at ``goal - offset`` while the finger and tendon settle on it, the servo's goal kept at
    ``goal + per_unit x`` the effort that holds the shaft against the tendon; then the goal
    where the effort is ``effort`` (NaN: the holding one) in force, no delay line (the
    finger was already there)."""
    shaft = goal - offset
    for _ in range(steps):
        settle[1] = goal + per_unit * k[K_UPN] * x[X_TEN]
        x[X_TH] = shaft
        x[X_VM] = 0.0
        advance_in(x, settle, k, dsegs, o, e, dt, -1.0, w)
    if not math.isnan(effort):
        settle[1] = goal + per_unit * effort
    x[X_TH] = shaft
    x[X_VM] = 0.0
    x[X_REF] = settle[1]
    line[0:5] = settle
    line[5:10] = settle
    line[10] = 1.0


@njit(cache=True)
def _prime(x: np.ndarray, t: np.ndarray, rows: np.ndarray, i: int, delay: float,
           line: np.ndarray, due: np.ndarray, queued: np.ndarray, ends: np.ndarray) -> None:
    """A segment restarting at row ``i`` with the delay line's worth of recorded commands
    (``finger_dynamic._primed``): the commands written less than ``delay`` before row ``i``
    are pending, due ``delay`` after they were written; the settling command stays in force
    until the first is due."""
    j0 = i - 1
    while j0 > 0 and t[j0] > t[i] - delay:
        j0 -= 1
    ends[0] = ends[1]
    if t[j0] <= t[i] - delay:
        j0 += 1
    for j in range(j0, i):
        due[ends[1]] = x[X_T] + (t[j] + delay - t[i])
        queued[ends[1], :] = rows[j]
        ends[1] += 1
    line[5:10] = rows[i - 1]
    line[10] = 1.0


@njit(cache=True, nogil=True)  # threads run simulations side by side (sim.parallel_runs)
def simulate_rows(x0: np.ndarray, t: np.ndarray, rows: np.ndarray, nsub: np.ndarray,
                  active: np.ndarray, restart: np.ndarray, effort: np.ndarray,
                  has_restart: bool, dt_s: float,
                  settle_steps: int, k: np.ndarray, dsegs: np.ndarray, o: np.ndarray,
                  e: np.ndarray, delay: float, offset: float, per_unit: float,
                  lead: float, out: np.ndarray) -> None:
    """Motor and proximal angle (``out[i]``) at every active row, each row's command held for
    ``nsub[i]`` steps over the span to the next row, the last ``lead`` share of them (rounded
    as ``finger_dynamic.lead_steps``) under the next row's command; after inactive rows a
    segment restarts at the measured angle ``restart[i]`` and effort ``effort[i]`` (held
    ``settle_steps``: :func:`_hold`; ``offset`` the sensor offset, ``per_unit`` the set-point
    per unit of effort), with the commands of the last delay pending (:func:`_prime`)."""
    n_rows = rows.shape[0]
    cap = int(nsub.sum()) + (settle_steps + 2) * n_rows + 1
    due = np.empty(cap)
    queued = np.empty((cap, 5))
    x = x0.copy()
    line = np.zeros(11)
    line[0:5] = _HOLD
    ends = np.zeros(2, dtype=np.int64)
    settle = np.array([0.0, 0.0, 0.0, 0.0, 1.0])
    w = work_array(k)
    was_active = True
    for i in range(n_rows):
        if not active[i]:
            was_active = False
            continue
        if not was_active and has_restart:
            x[:] = x0
            ends[0] = ends[1]
            _hold(x, settle, restart[i], effort[i], offset, per_unit, settle_steps, dt_s, k,
                  dsegs, o, e, line, w)
            if delay > 0.0 and i > 0:
                _prime(x, t, rows, i, delay, line, due, queued, ends)
            was_active = True
        out[i, 0] = x[X_TH]
        out[i, 1] = x[X_PHI]
        if i + 1 < n_rows:
            span = t[i + 1] - t[i]
            late = min(nsub[i], max(0, int(math.floor(lead * nsub[i] + 0.5))))
            _run(x, rows[i], rows[i + 1], nsub[i] - late, nsub[i], span / nsub[i], k, dsegs,
                 o, e, delay, line, due, queued, ends, w)


def simulate_compiled(p: FingerParams, eff: EffectSet, data: DynamicData, dt_s: float,
                      settle_s: float) -> np.ndarray:
    """The arrays of :func:`simulate_rows` from ``sim.finger_dynamic``'s arguments; the
    output column as ``simulate_dynamic`` returns it (all NaN if the run left the finite
    numbers, where the Python step raises)."""
    from sim import compiled as cp
    from sim.contact import ContactObject
    from sim.finger import initial_finger_state
    from sim.finger_dynamic import goal_per_unit, row_steps

    t = np.asarray(data.t_s, dtype=np.float64)
    n = len(t)
    nsub = np.ones(n, dtype=np.int64)
    if n > 1:
        nsub[:-1] = row_steps(t, dt_s)
    active = (np.ones(n, dtype=np.bool_) if data.active is None
              else np.asarray(data.active, dtype=np.bool_))
    goals = data.restart_goal_rad
    restart = np.zeros(n) if goals is None else np.asarray(goals, dtype=np.float64)
    effort = (np.full(n, math.nan) if data.restart_effort_units is None
              else np.asarray(data.restart_effort_units, dtype=np.float64))
    out = np.full((n, 2), math.nan)
    k, dsegs = cp.pack_params(p)
    simulate_rows(cp.state_array(initial_finger_state(p)), t, _rows(data.commands), nsub,
                  active, restart, effort, goals is not None, float(dt_s), int(settle_s / dt_s), k,
                  dsegs, cp.pack_object(ContactObject(kind="none")), cp.pack_effects(eff),
                  float(cp.command_delay(p, eff)), float(eff.sensor_offset),
                  goal_per_unit(p, eff), float(data.input_lead), out)
    off = eff.sensor_offset
    if data.output == "motor_angle_rad":
        y = (out[:, 0] + off) * data.out_scale
    else:
        y = (out[:, 1] + off) * 1.0
    y[~active] = math.nan
    if not np.all(np.isfinite(y[active])):
        y[:] = math.nan
    return y


_ROWS: dict[int, tuple[tuple[MotorCommand, ...], np.ndarray]] = {}


def _rows(commands: tuple[MotorCommand, ...]) -> np.ndarray:
    """The commands as an (n, 5) array (cached per commands tuple: the fit reuses it)."""
    from sim.compiled import command_row

    hit = _ROWS.get(id(commands))
    if hit is not None and hit[0] is commands:
        return hit[1]
    arr = np.array([command_row(c) for c in commands], dtype=np.float64).reshape(-1, 5)
    if len(_ROWS) > 8:
        _ROWS.clear()
    _ROWS[id(commands)] = (commands, arr)
    return arr
