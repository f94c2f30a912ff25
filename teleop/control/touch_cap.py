"""Model-mediated rendering's touch caps: a new touch is not squeezed deeper than the operator
can have felt.

Under delay the operator closes the trigger on nothing he can feel: the hand's contact model
(:mod:`teleop.control.contact_model`) has to travel hand -> controller -> master before the
trigger renders it.  Two caps hold a finger's new touch where the model renders a light touch,
``contact + touch_force_n / k`` (``k`` in N of trigger force per rad of set-point), until the
touch is known downstream:

- :func:`unseen_touch_cap` (controller) until the master echoes a command that carried the
  touch's model: the master link's round trip;
- :func:`hand_touch_cap` (hand) until a command arrives that the controller computed from a
  hand state that already had the touch (``HandCommand.hand_echo_t_s``): the hand link's round
  trip, which the controller cannot cover because it does not know of the touch yet.

Both are pure functions over explicit state; neither adds energy (a cap only lowers a
set-point).
"""

from __future__ import annotations

import math
from dataclasses import replace

from teleop.control.contact_model import FingerModel
from teleop.control.interface import ControlParams
from teleop.messages import HandCommand, HandMode, MasterState

Triple = tuple[float, float, float]
NO_TOUCH: Triple = (math.nan, math.nan, math.nan)


def touch_force_n(p: ControlParams) -> float:
    """The trigger force a new touch is held at until the operator can have felt it
    (``contact_model.touch_force_n``, at most the trigger's largest force)."""
    f = p.force_max_n
    if p.contact_model is not None:
        f = min(f, p.contact_model.touch_force_n)
    return f


def touch_depth_rad(p: ControlParams, k_n_per_rad: float) -> float:
    """How far beyond contact :func:`touch_force_n` is rendered, for a model of
    ``k_n_per_rad`` N of trigger force per rad of set-point."""
    return touch_force_n(p) / k_n_per_rad


def feel_time_s(p: ControlParams) -> float:
    """How long the master must have rendered a touch before the controller's cap opens."""
    return p.contact_model.touch_feel_s if p.contact_model is not None else 0.0


def unseen_touch_cap(since: Triple, p: ControlParams, model: tuple[float, ...],
                     master: MasterState | None, setpoints: Triple, t_s: float,
                     felt: Triple = NO_TOUCH) -> tuple[Triple, Triple, Triple]:
    """Controller side: until the operator can have felt the touch, the finger's set-point is
    capped at ``contact + touch_force_n / k``.  Felt: the master has echoed a command that
    carried the touch's model (``MasterState.echo_t_s >= since``), and the master state is
    ``touch_feel_s`` or more (master clock, ``felt``: when the master got that command) after
    the master first rendered it, so the trigger position it reports is the operator's answer
    to the force, not the blind squeeze before it.  At zero delay a first touch is held for
    ``touch_feel_s``; under delay the operator, who closed on nothing he could feel, does not
    drive the hand through the object meanwhile.  A model kept between grasps is not a new
    touch.  ``model``: the forwarded models (N per rad).  Returns (``since``, ``felt``,
    set-points)."""
    if model[1] <= 0.0 and model[3] <= 0.0 and model[5] <= 0.0:  # no model: nothing capped
        return NO_TOUCH, NO_TOUCH, (setpoints[0], setpoints[1], setpoints[2])
    # without a master state nothing is echoed: an echo at -inf is before every touch
    echo = master.echo_t_s if master is not None else -math.inf
    t_m = master.header.t_s if master is not None else math.nan
    held = master.echo_held_s if master is not None else math.nan
    feel = feel_time_s(p)
    since0, felt0, sp0 = _finger_cap(model[0], model[1], since[0], felt[0], setpoints[0], p,
                                     t_s, echo, t_m, held, feel)
    since1, felt1, sp1 = _finger_cap(model[2], model[3], since[1], felt[1], setpoints[1], p,
                                     t_s, echo, t_m, held, feel)
    since2, felt2, sp2 = _finger_cap(model[4], model[5], since[2], felt[2], setpoints[2], p,
                                     t_s, echo, t_m, held, feel)
    return (since0, since1, since2), (felt0, felt1, felt2), (sp0, sp1, sp2)


def _finger_cap(c: float, k: float, since: float, felt: float, setpoint: float,
                p: ControlParams, t_s: float, echo: float, t_m: float, held: float,
                feel: float) -> tuple[float, float, float]:
    """One finger of :func:`unseen_touch_cap`: (since, felt, set-point); ``echo``, ``t_m``
    and ``held``: the master state's echo, time and hold (-inf, nan, nan without one)."""
    if k <= 0.0:
        return math.nan, math.nan, setpoint
    t0 = since if math.isfinite(since) else t_s
    t1 = felt
    if not math.isfinite(t1) and echo >= t0:
        t1 = t_m - held
    if math.isfinite(t1) and t_m - t1 >= feel:
        return t0, t1, setpoint
    return t0, t1, min(setpoint, c + touch_depth_rad(p, k))


def _valid(m: FingerModel | None) -> tuple[float, float] | None:
    """``(contact_rad, k in pressure units per rad)`` of a valid model, else None."""
    if m is None or not m.valid or not math.isfinite(m.stiffness):
        return None
    return m.contact_rad, m.stiffness


def touch_since(since: Triple, models: tuple[FingerModel, ...] | None, t_s: float) -> Triple:
    """Hand side: per finger, the hand time at which its current contact model became valid
    (kept while it stays valid; nan without a model or without a hand time)."""
    if models is None:
        return NO_TOUCH
    out = []
    for i in range(3):
        ok = i < len(models) and _valid(models[i]) is not None
        out.append((since[i] if math.isfinite(since[i]) else t_s) if ok else math.nan)
    return tuple(out)  # type: ignore[return-value]


def hand_touch_cap(p: ControlParams, models: tuple[FingerModel, ...] | None, since: Triple,
                   command: HandCommand | None, pressures: Triple | None = None,
                   motor_rad: Triple | None = None) -> HandCommand | None:
    """Hand side: ``command`` with each finger whose touch (valid since ``since``) the
    controller had not yet seen when it computed the command (``hand_echo_t_s < since``)
    capped at ``contact + touch_force_n / k``, and, once the finger's measured peak pressure
    (``pressures``) renders ``touch_force_n`` or more, held where its motor is
    (``motor_rad``, joint side): the model's stiffness is only a prior on a first touch, the
    pressure is measured; the same command when no cap binds."""
    if (command is None or models is None or command.mode != HandMode.POSITION
            or p.force_per_pressure_n <= 0.0):
        return command
    sp = list(command.finger_setpoint_rad)
    bound = False
    p_touch = touch_force_n(p) / p.force_per_pressure_n
    for i in range(min(3, len(models), len(sp))):
        if not math.isfinite(since[i]) or command.hand_echo_t_s >= since[i]:
            continue
        m = _valid(models[i])
        if m is None:
            continue
        cap = m[0] + touch_depth_rad(p, m[1] * p.force_per_pressure_n)
        if pressures is not None and motor_rad is not None and pressures[i] >= p_touch:
            cap = min(cap, motor_rad[i])
        if sp[i] > cap:
            sp[i], bound = cap, True
    if not bound:
        return command
    return replace(command, finger_setpoint_rad=tuple(sp))
