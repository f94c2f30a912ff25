"""A ``teleop up --record`` hand recording (``hand.csv``), one finger, as the finger model's data.

Columns used for finger ``N`` (1-3):

* command: ``setpoint_rad_fN``, the joint set-point the hand service applied on that row (it holds
  until the next row).  The hand service commands position mode only, so the motor goal is
  ``1.42 x`` the set-point clamped to the joint travel; a ``mode_fN`` column, if a recorder
  writes one (0 position, 1 force, with ``force_units_fN``), is honoured row by row;
* output: ``motor_angle_rad_fN`` (the driver's joint-side motor angle, shaft / 1.42) or
  ``proximal_angle_rad_fN``;
* driver: a recording whose ``# hand_backend:`` is ``dynamixel`` also says the driver's moving
  speed and overload back-off (``# speed_rad_s:``, ``# overload_finger_units:``,
  ``# load_filter:``); the targets it wrote are rebuilt from ``motor_load_units_fN`` and the
  motor angle (:func:`dynamixel_targets`), and the moves are paced at that speed;
* contact: ``contacts_fN`` (sensors in contact).  Rows in contact are excluded: the object is
  not known from the recording.  The simulation stops there and restarts after the contact
  (and after a gap, ``--split-gaps``) at the measured state: the finger at rest on the
  measured motor angle, the servo's effort the recorded ``motor_load_units_fN`` (without
  that column, the effort that holds the finger there); the first ``SETTLE_ROWS_S`` after a
  restart are not compared (the finger's speed there is not known).

The hand's own rate (40 Hz by default) and irregular timing are used as recorded.  ``t_s`` is
the hand loop's deadline; a recording with ``read_t_s`` and ``write_t_s`` (when the hand service
really read the servos and wrote the set-points, since 2026-11-26) is simulated on those times
(:func:`on_clock`): the output is compared at its read time and each row's command applies from
its write time (a dynamixel overload back-off written during a read, from that read).  Without
them (older recordings) every row is read and written at ``t_s``.
"""

from __future__ import annotations

import numpy as np

from sim.finger import MotorCommand
from sim.finger_dynamic import DynamicData
from sim.params import JOINT_RATIO
from teleop.devices.dynamixel_hand import BACKOFF_RAD
from teleop.errors import RecordingError
from teleop.recording import Recording
from teleop.recording_checks import MIN_COMPARED, finite_column, gap_rows

TRAVEL_RAD = 3.6           # joint travel the hand clamps set-points to (hand.dynamixel default)
SETTLE_ROWS_S = 0.15       # not compared after a restart
START_OPEN_RAD = 0.01      # a first motor angle beyond this: the recording starts mid-motion


def is_hand_recording(rec: Recording) -> bool:
    """A hand service recording (per-finger columns)."""
    return rec.meta_value("role") == "hand" or any(
        c.startswith(("setpoint_rad_f", "motor_angle_rad_f")) for c in rec.columns)


def _col(rec: Recording, name: str, finger: int) -> np.ndarray:
    if not rec.has(name):
        raise RecordingError(f"{rec.source}: no column {name!r} for --finger {finger} (a hand "
                             "recording has fingers 1, 2 and 3)")
    return finite_column(rec, name)


def _meta_float(rec: Recording, key: str) -> float:
    raw = rec.meta_value(key)
    try:
        return float(raw)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise RecordingError(f"{rec.source}: a dynamixel hand recording needs a numeric "
                             f"'# {key}:' line (got {raw!r})") from None


def overloaded(load_units: np.ndarray, overload_units: float, load_filter: float) -> np.ndarray:
    """Rows after whose read the dynamixel driver's filtered load (``f = a new + (1 - a) f``)
    is above the overload threshold."""
    out = np.zeros(len(load_units), bool)
    f = 0.0
    for i, load in enumerate(load_units):
        f = load_filter * float(load) + (1.0 - load_filter) * f
        out[i] = abs(f) > overload_units
    return out


def backed_off(joint_rad: np.ndarray) -> np.ndarray:
    """The driver's overload back-off target: the present angle - 0.05 rad, in the travel."""
    return np.clip(np.asarray(joint_rad, float) - BACKOFF_RAD, 0.0, TRAVEL_RAD)


def dynamixel_targets(setpoint_rad: np.ndarray, joint_rad: np.ndarray, load_units: np.ndarray,
                      overload_units: float, load_filter: float) -> np.ndarray:
    """The joint targets the dynamixel driver wrote, row by row, rebuilt from the recording:
    the set-point (already clamped to the travel), except while overloaded
    (:func:`overloaded`), when the target is held at :func:`backed_off`."""
    over = overloaded(load_units, overload_units, load_filter)
    out = np.array(setpoint_rad, dtype=float)
    out[over] = np.minimum(out[over], backed_off(joint_rad)[over])
    return out


def on_clock(data: DynamicData, read_t_s: np.ndarray, write_t_s: np.ndarray,
             read_cmds: tuple[MotorCommand, ...]) -> DynamicData:
    """``data`` (one row per hand tick, command ``i`` from ``t_s[i]``) on the times the hand
    was really read and written: two rows per tick, the read (compared; command
    ``read_cmds[i]``, what holds from the read on) and the write (``data.commands[i]``).
    A tick that wrote nothing (NaN write time) keeps the read row's command.  Times are made
    strictly increasing (by 1 us at most where a write was stamped at its read)."""
    n = len(data.t_s)
    t = np.empty(2 * n)
    t[0::2], t[1::2] = read_t_s, np.where(np.isfinite(write_t_s), write_t_s, read_t_s)
    for i in range(1, 2 * n):
        t[i] = max(t[i], t[i - 1] + 1e-6)
    wrote = np.isfinite(write_t_s)
    cmds = tuple(c for i in range(n) for c in (
        read_cmds[i], data.commands[i] if wrote[i] else read_cmds[i]))

    def twice(a: np.ndarray | None) -> np.ndarray | None:
        return None if a is None else np.repeat(a, 2)

    return DynamicData(t, cmds, np.repeat(data.y, 2), data.output, 2 * data.keep,
                       data.physics_dt_s, data.out_scale, twice(data.active),
                       twice(data.restart_goal_rad), data.note,
                       twice(data.restart_effort_units))


def _clock_columns(rec: Recording) -> tuple[np.ndarray, np.ndarray] | None:
    """``(read_t_s, write_t_s)`` when the recording has them (read times finite, increasing)."""
    if not (rec.has("read_t_s") and rec.has("write_t_s")):
        return None
    r, w = rec.column("read_t_s"), rec.column("write_t_s")
    if not np.all(np.isfinite(r)) or np.any(np.diff(r) <= 0):
        raise RecordingError(f"{rec.source}: column 'read_t_s' is not finite and increasing "
                             f"at data row {_first_bad(r) + 1}")
    return r, w


def _first_bad(r: np.ndarray) -> int:
    bad = ~np.isfinite(r)
    bad[1:] |= np.diff(r) <= 0
    return int(np.argmax(bad))


def hand_finger_data(rec: Recording, finger: int, output: str = "motor_angle_rad",
                     fit_rate_hz: float = 50.0, split_gaps: bool = False) -> DynamicData:
    """Commands, measurement and contact mask of one finger of a hand recording."""
    if finger not in (1, 2, 3):
        raise RecordingError(f"{rec.source}: --finger {finger}: a hand has fingers 1, 2 and 3 "
                             f"(no column 'setpoint_rad_f{finger}')")
    if output not in ("motor_angle_rad", "proximal_angle_rad"):
        raise RecordingError(f"{rec.source}: --output must be motor_angle_rad or "
                             f"proximal_angle_rad for a hand recording (got {output!r})")
    gaps = gap_rows(rec, split_gaps, can_split=True)
    t = rec.t_s
    sp = _col(rec, f"setpoint_rad_f{finger}", finger)
    motor = _col(rec, f"motor_angle_rad_f{finger}", finger)
    y = _col(rec, f"{output}_f{finger}", finger)
    mode = rec.column(f"mode_f{finger}") if rec.has(f"mode_f{finger}") else np.zeros(len(t))
    force = (_col(rec, f"force_units_f{finger}", finger) if np.any(mode == 1)
             else np.zeros(len(t)))
    goal, speed = np.clip(sp, 0.0, TRAVEL_RAD), 0.0
    read_goal = np.concatenate([goal[:1], goal[:-1]])  # what holds from each read on
    driver = rec.meta_value("hand_backend")
    if driver == "dynamixel":  # its targets back off while overloaded; its moves are paced
        speed = JOINT_RATIO * _meta_float(rec, "speed_rad_s")
        over = overloaded(_col(rec, f"motor_load_units_f{finger}", finger),
                          _meta_float(rec, "overload_finger_units"),
                          _meta_float(rec, "load_filter"))
        back = backed_off(motor)
        goal = np.where(over, np.minimum(goal, back), goal)
        read_goal = np.concatenate([goal[:1], goal[:-1]])
        read_goal = np.where(over, np.minimum(read_goal, back), read_goal)
    read_mode = np.concatenate([mode[:1], mode[:-1]])
    read_force = np.concatenate([force[:1], force[:-1]])

    def commands(goals: np.ndarray, modes: np.ndarray, forces: np.ndarray
                 ) -> tuple[MotorCommand, ...]:
        return tuple(MotorCommand("force", force_units=float(f)) if m == 1 else
                     MotorCommand("position", goal_rad=JOINT_RATIO * float(g),
                                  speed_rad_s=speed)
                     for g, m, f in zip(goals, modes, forces, strict=True))

    cmds = commands(goal, mode, force)
    # the servo's effort where a segment restarts (an empty cell: the effort that holds it)
    load = (rec.column(f"motor_load_units_f{finger}")
            if rec.has(f"motor_load_units_f{finger}") else None)
    contact = (rec.column(f"contacts_f{finger}") > 0 if rec.has(f"contacts_f{finger}")
               else np.zeros(len(t), bool))
    active = ~contact
    # a recording cut after its start (--skip) begins with the finger anywhere: the first row
    # is not simulated, the next restarts at the measured angle (as after a contact)
    active[0] = active[0] and abs(float(motor[0])) < START_OPEN_RAD
    active[gaps] = False  # the row before a gap is not simulated: the next one restarts
    compare = active.copy()
    n_seg = 0
    for i in np.flatnonzero(active[1:] & ~active[:-1]) + 1:  # restarts
        n_seg += 1
        compare[(t >= t[i]) & (t < t[i] + SETTLE_ROWS_S)] = False
    dt_rec = float(np.median(np.diff(t)))
    every = max(1, int(round(1.0 / (fit_rate_hz * dt_rec))))
    idx = np.flatnonzero(compare)
    keep = idx[::every]
    if len(keep) < MIN_COMPARED:
        raise RecordingError(f"{rec.source}: finger {finger} is in contact on {contact.sum()} of "
                             f"{len(t)} rows ('contacts_f{finger}'); {len(keep)} contact-free "
                             f"samples is too few to diagnose (need {MIN_COMPARED})")
    notes = []
    if len(gaps):
        notes.append(f"{len(gaps)} gap(s) in 't_s' (first after data row {gaps[0] + 1}, "
                     f"longest {float(np.max(np.diff(t)[gaps])):.3g} s): the simulation "
                     "restarts after each (--split-gaps)")
    if contact.any():
        notes.append(f"{int(contact.sum())} of {len(t)} rows in contact ('contacts_f{finger}' "
                     f"> 0, {float(np.sum(np.diff(t)[contact[:-1]])):.1f} s) excluded: the "
                     f"object is not in the recording; the simulation restarts {n_seg} time(s) "
                     f"at the measured motor angle{' and load' if load is not None else ''}, "
                     f"{SETTLE_ROWS_S:g} s after each not compared")
    clock = _clock_columns(rec)
    if clock is None:
        notes.append("no 'read_t_s'/'write_t_s' columns: read and written at 't_s' (the "
                     "hand loop's deadline)")
    note = "; ".join(notes)
    data = DynamicData(t, cmds, y, output, keep, 1e-3,
                       out_scale=1.0 / JOINT_RATIO if output == "motor_angle_rad" else 1.0,
                       active=None if active.all() else active,
                       restart_goal_rad=JOINT_RATIO * motor,  # joint-side motor angle -> shaft
                       restart_effort_units=load, note=note)
    if clock is None:
        return data
    return on_clock(data, clock[0], clock[1], commands(read_goal, read_mode, read_force))
