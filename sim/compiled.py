"""The compiled engine's Python side: packing the model's dataclasses into arrays and back.

The compiled step (:mod:`sim.compiled_step`) works on flat float64 arrays; this module turns
``FingerParams``/``ContactObject``/``EffectSet``/``MotorCommand``/``FingerState`` into them
and back, keeps the command delay line (``FingerState.command``) in Python exactly as
``sim.finger._step`` does, and offers drop-in pure steps with the reference's signatures::

    state = compiled_finger_step(state, cmd, params, obj, effects, dt_s)   # = finger_step
    hand = compiled_hand_step(hand, hcmd, hand_params, obj, effects, dt_s)  # = hand_step

(each call pays the packing; loops that step many times use :mod:`sim.compiled_runs`).
:func:`warm_up` compiles the kernels or loads them from numba's disk cache; call it before a
real-time loop so that no step stalls on compilation.
"""

from __future__ import annotations

import math
import time

import numpy as np

from sim.compiled_kernel import K_PADSTART, K_RIP_S, K_SFRAC, K_SPIECES, N_K, X_FLEX
from sim.contact import ContactObject
from sim.finger import _consts
from sim.hand import HandMotorCommand, HandParams, HandSimState, _objects
from sim.motor import HOLD_ZERO, MotorCommand
from sim.params import FingerParams
from sim.state import FingerState
from teleop.effects import EffectSet

_MODES = {"position": 0.0, "force": 1.0, "velocity": 2.0}
_KINDS = {"none": 0.0, "cylinder": 1.0, "block": 2.0}
_PROX_PAD_START_M = 0.010  # as sim.finger
CommandLine = tuple[MotorCommand, MotorCommand | None, tuple[tuple[float, MotorCommand], ...]]
_PACKED: dict[int, tuple[FingerParams, np.ndarray, np.ndarray]] = {}


def pack_params(p: FingerParams) -> tuple[np.ndarray, np.ndarray]:
    """(constants ``k``, damping pieces ``dsegs``) of ``p`` (cached per params object)."""
    hit = _PACKED.get(id(p))
    if hit is not None and hit[0] is p:
        return hit[1], hit[2]
    c = _consts(p)
    k = np.empty(N_K)
    k[:27] = c[:27]
    k[27:31] = c[28:32]
    k[31] = p.n_flex
    k[K_PADSTART] = _PROX_PAD_START_M
    k[K_SFRAC] = c[32]
    k[K_SPIECES:K_RIP_S] = np.array(c[33], dtype=np.float64).ravel() if c[32] != 0.0 else 0.0
    k[K_RIP_S:] = c[34:37]
    dsegs = np.array(c[27], dtype=np.float64).reshape(-1, 4)
    if len(_PACKED) > 64:
        _PACKED.clear()
    _PACKED[id(p)] = (p, k, dsegs)
    return k, dsegs


def pack_object(obj: ContactObject) -> np.ndarray:
    """The object array ``o``."""
    return np.array([_KINDS[obj.kind], obj.x_m, obj.y_m, obj.radius_m, obj.stiffness_n_per_m,
                     obj.damping_n_s_per_m, obj.core_depth_m, obj.core_stiffness_n_per_m,
                     obj.yield_force_n, obj.yield_hardening_n_per_m])


def pack_effects(eff: EffectSet) -> np.ndarray:
    """The effects array ``e`` (EffectSet's fields in order)."""
    return np.array([eff.dead_time, eff.coulomb_friction, eff.asymmetric_friction,
                     eff.stiction, eff.backlash, eff.actuator_saturation, eff.actuator_gain,
                     eff.actuator_lag, eff.sensor_offset, eff.series_compliance,
                     eff.nonlinear_stiffness, eff.gravity])


def command_row(cmd: MotorCommand) -> list[float]:
    """The command array ``c`` as a list."""
    return [_MODES[cmd.mode], cmd.goal_rad, cmd.speed_rad_s, cmd.force_units, cmd.torque_limit]


def state_array(s: FingerState) -> np.ndarray:
    """The state array ``x`` of ``s``."""
    return np.array([s.t_s, s.prox_rad, s.prox_vel_rad_s, s.motor_rad, s.motor_vel_rad_s,
                     s.tendon_force_n, *s.drive, *s.pads, *s.crush_m, *s.flex_rad,
                     *s.flex_vel_rad_s])


def state_from_array(x: np.ndarray, command: CommandLine) -> FingerState:
    """The ``FingerState`` of array ``x`` with the delay line ``command``."""
    v = x.tolist()
    n = (len(v) - X_FLEX) // 2
    return FingerState(v[0], v[1], v[2], tuple(v[X_FLEX:X_FLEX + n]),
                       tuple(v[X_FLEX + n:]), v[3], v[4], v[5], (v[6], v[7], v[8], v[9]),
                       (v[10], v[11], v[12], v[13]), command, (v[14], v[15]))


def command_delay(p: FingerParams, eff: EffectSet) -> float:
    """Total command delay (driver + dead_time effect), as ``sim.finger._step``."""
    return p.command_delay_s + eff.dead_time


def next_command(line: CommandLine, cmd: MotorCommand, t: float,
                 delay: float) -> CommandLine:
    """The delay line after receiving ``cmd`` at time ``t`` (``sim.finger._step``'s logic);
    its first item is the command in force for the step from ``t``."""
    active, last, pending = line
    if delay <= 0.0:
        return cmd, cmd, pending
    if cmd is not last and cmd != last:
        pending = (*pending, (t + delay, cmd))
    while pending and pending[0][0] <= t + 1e-12:
        active = pending[0][1]
        pending = pending[1:]
    return active, cmd, pending


def compiled_finger_step(state: FingerState, cmd: MotorCommand, params: FingerParams,
                         obj: ContactObject, effects: EffectSet, dt_s: float,
                         fixed_tension_n: float = -1.0) -> FingerState:
    """``sim.finger.finger_step`` through the compiled step (``fixed_tension_n >= 0``: the
    hung weight of ``sim.finger.hung_weight_step``)."""
    from sim.compiled_step import advance

    line = next_command(state.command, cmd, state.t_s, command_delay(params, effects))
    x = state_array(state)
    k, dsegs = pack_params(params)
    advance(x, np.array(command_row(line[0])), k, dsegs, pack_object(obj),
            pack_effects(effects), float(dt_s), float(fixed_tension_n))
    return state_from_array(x, line)


def compiled_hung_weight_step(state: FingerState, params: FingerParams, force_n: float,
                              dt_s: float, effects: EffectSet) -> FingerState:
    """``sim.finger.hung_weight_step`` through the compiled step."""
    return compiled_finger_step(state, HOLD_ZERO, params, ContactObject(), effects, dt_s,
                                max(force_n, 0.0))


def hand_arrays(params: HandParams) -> np.ndarray:
    """The preshape constants ``hp`` of :func:`sim.compiled_runs.preshape_step`."""
    lo, hi = params.preshape_limits_rad
    return np.array([params.preshape_inertia_kg_m2, params.preshape_kp_nm_per_rad,
                     params.preshape_damping_nm_s_per_rad, params.preshape_max_torque_nm, lo,
                     hi])


def run_hand_steps(state: HandSimState, cmd: HandMotorCommand, params: HandParams,
                   obj: ContactObject | tuple[ContactObject, ...], effects: EffectSet,
                   dt_s: float, steps: int, t_end: float = math.inf,
                   audit: tuple[list[float], list[float]] | None = None) -> HandSimState:
    """Up to ``steps`` hand steps (stopping once ``t + dt/2 > t_end``) in one compiled call;
    with ``audit`` = (delivered, taken) lists the object work is added to them in place."""
    from sim.compiled_runs import run_hand

    fp = params.finger
    delay = command_delay(fp, effects)
    if delay > 0.0 and steps > 1:  # the delay line is per step: one compiled call a step
        for _ in range(steps):
            if state.t_s + 0.5 * dt_s > t_end:
                break
            state = run_hand_steps(state, cmd, params, obj, effects, dt_s, 1, t_end, audit)
        return state
    lines = [next_command(f.command, c, f.t_s, delay) for f, c in zip(state.fingers,
                                                                         cmd.fingers,
                                                                         strict=True)]
    xs = np.array([state_array(f) for f in state.fingers])
    cs = np.array([command_row(line[0]) for line in lines])
    pre = np.array([state.t_s, state.preshape_rad, state.preshape_vel_rad_s])
    objs = np.array([pack_object(o) for o in _objects(obj)])
    k, dsegs = pack_params(fp)
    acc = np.array(audit if audit is not None else ([0.0] * 3, [0.0] * 3), dtype=np.float64)
    # plain float/int arguments: one compiled signature, the one warm_up loads
    done = run_hand(xs, cs, pre, float(cmd.preshape_goal_rad), hand_arrays(params), k, dsegs,
                    objs, pack_effects(effects), float(dt_s), int(steps), float(t_end),
                    audit is not None, acc[0], acc[1])
    if done == 0:
        return state
    if audit is not None:
        audit[0][:] = acc[0].tolist()
        audit[1][:] = acc[1].tolist()
    fs = tuple(state_from_array(xs[i], lines[i]) for i in range(3))
    return HandSimState(float(pre[0]), (fs[0], fs[1], fs[2]), float(pre[1]), float(pre[2]))


def compiled_hand_step(state: HandSimState, cmd: HandMotorCommand, params: HandParams,
                       obj: ContactObject | tuple[ContactObject, ...], effects: EffectSet,
                       dt_s: float) -> HandSimState:
    """``sim.hand.hand_step`` through the compiled step."""
    return run_hand_steps(state, cmd, params, obj, effects, dt_s, 1)


def warm_up(finger: bool = True) -> float:
    """Compile the hand loop (and with ``finger`` the finger's), or load them from numba's disk
    cache; returns the seconds spent.  Call before a real-time loop: no step stalls after."""
    from sim.compiled_runs import run_finger
    from sim.finger import default_finger_params, initial_finger_state
    from sim.hand import default_hand_params, initial_hand_state

    t0 = time.perf_counter()
    p = default_finger_params()
    hp = default_hand_params(p)
    hold = MotorCommand()
    run_hand_steps(initial_hand_state(hp), HandMotorCommand((hold, hold, hold)), hp,
                   ContactObject(kind="cylinder"), EffectSet(), 1e-3, 2,
                   audit=([0.0] * 3, [0.0] * 3))
    if finger:
        x = state_array(initial_finger_state(p))
        k, dsegs = pack_params(p)
        run_finger(x, np.zeros((1, 5)), np.full(1, 1e-3), k, dsegs,
                   pack_object(ContactObject()), pack_effects(EffectSet()), -1.0,
                   np.zeros(2, dtype=np.bool_), np.zeros((0, x.size)))
    return time.perf_counter() - t0
