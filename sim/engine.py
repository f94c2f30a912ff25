"""Physics engines by config name (``hand.sim.engine``): the Python reference or compiled.

Both advance the same model (:mod:`sim.finger`, :mod:`sim.hand`); ``"python"`` is the
reference step, ``"compiled"`` the numba step of :mod:`sim.compiled_step`, held to the
reference within 1e-9 rad by ``tests/sim/test_compiled_engine.py``.  An engine runs a finger
through a command sequence (:meth:`Engine.run_finger`) and the hand between two reads
(:meth:`Engine.run_hand`), the two loops where the interpreter's per-step cost was paid::

    eng = engine("compiled")          # or "python"
    final, rows = eng.run_finger(state, cmds, dts, params, obj, effects, record)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from sim.contact import ContactObject
from sim.finger import finger_step, hung_weight_step
from sim.hand import HandMotorCommand, HandParams, HandSimState, hand_step
from sim.motor import MotorCommand
from sim.params import FingerParams
from sim.state import FingerState
from teleop.effects import EffectSet
from teleop.errors import UserInputError

ENGINES: tuple[str, ...] = ("compiled", "python")
DEFAULT_ENGINE = "compiled"
Audit = tuple[list[float], list[float]]


@dataclass(frozen=True, slots=True)
class Engine:
    """A physics engine: the name and its two loops (signatures of the ``_python_*`` ones)."""

    name: str
    run_finger: Callable[..., tuple[FingerState, list[FingerState]]]
    run_hand: Callable[..., HandSimState]


def _python_run_finger(state: FingerState, cmds: Sequence[MotorCommand], dts: Sequence[float],
                       params: FingerParams, obj: ContactObject, effects: EffectSet,
                       record: Sequence[bool], hung_n: float = -1.0,
                       ) -> tuple[FingerState, list[FingerState]]:
    """Step ``state`` under ``cmds[s]`` for ``dts[s]``; the states before step ``s`` where
    ``record[s]`` (``record[len(cmds)]``: the final state) are returned with the final one.
    ``hung_n >= 0`` hangs that weight on the detached tendon (``cmds`` then unused)."""
    rows: list[FingerState] = []
    for s, (cmd, dt) in enumerate(zip(cmds, dts, strict=True)):
        if record[s]:
            rows.append(state)
        if hung_n >= 0.0:
            state = hung_weight_step(state, params, hung_n, dt, effects)
        else:
            state = finger_step(state, cmd, params, obj, effects, dt)
    if record[len(cmds)]:
        rows.append(state)
    return state, rows


def _compiled_run_finger(state: FingerState, cmds: Sequence[MotorCommand],
                         dts: Sequence[float], params: FingerParams, obj: ContactObject,
                         effects: EffectSet, record: Sequence[bool], hung_n: float = -1.0,
                         ) -> tuple[FingerState, list[FingerState]]:
    """:func:`_python_run_finger` in one compiled call (the delay line computed first)."""
    from sim import compiled as cp
    from sim.compiled_runs import run_finger

    delay = cp.command_delay(params, effects)
    lines: list[cp.CommandLine] = []
    line = state.command
    t = state.t_s
    hung = hung_n >= 0.0
    if hung:
        cmds = [cp.HOLD_ZERO] * len(cmds)
    for cmd, dt in zip(cmds, dts, strict=True):  # the command in force at every step
        line = cp.next_command(line, cmd, t, delay)
        lines.append(line)
        t += dt
    rows_cmd = np.array([cp.command_row(ln[0]) for ln in lines]).reshape(-1, 5)
    x = cp.state_array(state)
    k, dsegs = cp.pack_params(params)
    rec = np.asarray(record, dtype=np.bool_)
    out = np.empty((int(rec.sum()), x.size))
    obj_used = ContactObject() if hung else obj
    run_finger(x, rows_cmd, np.asarray(dts, dtype=np.float64), k, dsegs,
               cp.pack_object(obj_used), cp.pack_effects(effects),
               float(max(hung_n, 0.0)) if hung else -1.0, rec, out)
    where = np.flatnonzero(rec).tolist()
    rows = [cp.state_from_array(out[r], lines[s - 1] if s else state.command)
            for r, s in enumerate(where)]
    final = cp.state_from_array(x, lines[-1]) if lines else state
    return final, rows


def _python_run_hand(state: HandSimState, cmd: HandMotorCommand, params: HandParams,
                     obj: ContactObject | tuple[ContactObject, ...], effects: EffectSet,
                     dt_s: float, steps: int, t_end: float = math.inf,
                     audit: Audit | None = None) -> HandSimState:
    """Up to ``steps`` hand steps, stopping once ``t + dt/2 > t_end``; with ``audit`` =
    (delivered, taken) the work on the object (``sim.audit``) is added per finger."""
    from sim.audit import object_work_j, pad_depths

    objs = obj if isinstance(obj, tuple) else (obj, obj, obj)
    fp = params.finger
    depths = [pad_depths(f, fp, objs[i]) for i, f in enumerate(state.fingers)] if audit else []
    for _ in range(steps):
        if state.t_s + 0.5 * dt_s > t_end:
            break
        state = hand_step(state, cmd, params, obj, effects, dt_s)
        if audit is not None:
            for i, f in enumerate(state.fingers):
                after = pad_depths(f, fp, objs[i])
                w = object_work_j(depths[i], after, objs[i], dt_s)
                depths[i] = after
                if w > 0.0:
                    audit[0][i] += w
                else:
                    audit[1][i] -= w
    return state


def _compiled_run_hand(*args: Any, **kwargs: Any) -> HandSimState:
    """``sim.compiled.run_hand_steps`` (numba imported on first use, not with the engine)."""
    from sim.compiled import run_hand_steps

    return run_hand_steps(*args, **kwargs)


_REGISTRY: dict[str, Callable[[], Engine]] = {
    "python": lambda: Engine("python", _python_run_finger, _python_run_hand),
    "compiled": lambda: Engine("compiled", _compiled_run_finger, _compiled_run_hand),
}


def engine(name: str = DEFAULT_ENGINE) -> Engine:
    """The engine registered under ``name`` (``hand.sim.engine``)."""
    if name not in _REGISTRY:
        raise UserInputError(f"unknown physics engine {name!r} (known: {', '.join(ENGINES)})")
    return _REGISTRY[name]()
