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
  not known from the recording.  The simulation stops there and restarts after the contact,
  settled at the measured motor angle; the first ``SETTLE_ROWS_S`` after a restart are not
  compared (the finger may still be moving).

The hand's own rate (40 Hz by default) and irregular timing are used as recorded.
"""

from __future__ import annotations

import numpy as np

from sim.finger import MotorCommand
from sim.finger_dynamic import DynamicData
from sim.params import JOINT_RATIO
from teleop.devices.dynamixel_hand import BACKOFF_RAD
from teleop.errors import RecordingError
from teleop.recording import Recording

TRAVEL_RAD = 3.6           # joint travel the hand clamps set-points to (hand.dynamixel default)
SETTLE_ROWS_S = 0.15       # not compared after a restart
MAX_GAP_FACTOR = 10.0      # a step this many median steps long is a gap
MIN_COMPARED = 40
START_OPEN_RAD = 0.01      # a first motor angle beyond this: the recording starts mid-motion


def is_hand_recording(rec: Recording) -> bool:
    """A hand service recording (per-finger columns)."""
    return rec.meta_value("role") == "hand" or any(
        c.startswith(("setpoint_rad_f", "motor_angle_rad_f")) for c in rec.columns)


def _col(rec: Recording, name: str, finger: int) -> np.ndarray:
    if not rec.has(name):
        raise RecordingError(f"{rec.source}: no column {name!r} for --finger {finger} (a hand "
                             "recording has fingers 1, 2 and 3)")
    v = rec.column(name)
    bad = ~np.isfinite(v)
    if bad.any():
        raise RecordingError(f"{rec.source}: column {name!r} is not finite at data row "
                             f"{int(np.argmax(bad)) + 1}")
    return v


def _gaps(rec: Recording, split: bool) -> np.ndarray:
    """Rows after which the recording has a gap (a stalled hand tick, e.g. bus retries):
    refused in one line unless ``split``, when the simulation restarts after each."""
    t = rec.t_s
    if len(t) < 3:
        raise RecordingError(f"{rec.source}: {len(t)} rows is too short to diagnose")
    dts = np.diff(t)
    med = float(np.median(dts))
    gap = dts > MAX_GAP_FACTOR * med
    if gap.any() and not split:
        i = int(np.argmax(gap))
        raise RecordingError(f"{rec.source}: column 't_s' has a gap of {dts[i]:.3g} s at data "
                             f"row {i + 2} (median step {med:.3g} s); split the recording, "
                             f"--skip {t[i + 1] - t[0]:.3g} past it, or --split-gaps")
    return np.flatnonzero(gap)


def _meta_float(rec: Recording, key: str) -> float:
    raw = rec.meta_value(key)
    try:
        return float(raw)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise RecordingError(f"{rec.source}: a dynamixel hand recording needs a numeric "
                             f"'# {key}:' line (got {raw!r})") from None


def dynamixel_targets(setpoint_rad: np.ndarray, joint_rad: np.ndarray, load_units: np.ndarray,
                      overload_units: float, load_filter: float) -> np.ndarray:
    """The joint targets the dynamixel driver wrote, row by row, rebuilt from the recording:
    the set-point (already clamped to the travel), except while the filtered load
    (``f = a new + (1 - a) f``) is above the overload threshold, when the target is held at
    the present angle - 0.05 rad (the driver's overload back-off)."""
    out = np.array(setpoint_rad, dtype=float)
    f = 0.0
    for i, (j, load) in enumerate(zip(joint_rad, load_units, strict=True)):
        f = load_filter * float(load) + (1.0 - load_filter) * f
        if abs(f) > overload_units:
            out[i] = min(out[i], min(max(float(j) - BACKOFF_RAD, 0.0), TRAVEL_RAD))
    return out


def hand_finger_data(rec: Recording, finger: int, output: str = "motor_angle_rad",
                     fit_rate_hz: float = 50.0, split_gaps: bool = False) -> DynamicData:
    """Commands, measurement and contact mask of one finger of a hand recording."""
    if finger not in (1, 2, 3):
        raise RecordingError(f"{rec.source}: --finger {finger}: a hand has fingers 1, 2 and 3 "
                             f"(no column 'setpoint_rad_f{finger}')")
    if output not in ("motor_angle_rad", "proximal_angle_rad"):
        raise RecordingError(f"{rec.source}: --output must be motor_angle_rad or "
                             f"proximal_angle_rad for a hand recording (got {output!r})")
    gaps = _gaps(rec, split_gaps)
    t = rec.t_s
    sp = _col(rec, f"setpoint_rad_f{finger}", finger)
    motor = _col(rec, f"motor_angle_rad_f{finger}", finger)
    y = _col(rec, f"{output}_f{finger}", finger)
    mode = rec.column(f"mode_f{finger}") if rec.has(f"mode_f{finger}") else np.zeros(len(t))
    force = (_col(rec, f"force_units_f{finger}", finger) if np.any(mode == 1)
             else np.zeros(len(t)))
    goal, speed = np.clip(sp, 0.0, TRAVEL_RAD), 0.0
    driver = rec.meta_value("hand_backend")
    if driver == "dynamixel":  # its targets back off while overloaded; its moves are paced
        speed = JOINT_RATIO * _meta_float(rec, "speed_rad_s")
        goal = dynamixel_targets(goal, motor, _col(rec, f"motor_load_units_f{finger}", finger),
                                 _meta_float(rec, "overload_finger_units"),
                                 _meta_float(rec, "load_filter"))
    cmds = tuple(MotorCommand("force", force_units=float(f)) if m == 1 else
                 MotorCommand("position", goal_rad=JOINT_RATIO * float(g), speed_rad_s=speed)
                 for g, m, f in zip(goal, mode, force, strict=True))
    contact = (rec.column(f"contacts_f{finger}") > 0 if rec.has(f"contacts_f{finger}")
               else np.zeros(len(t), bool))
    active = ~contact
    # a recording cut after its start (--skip) begins with the finger anywhere: the first row
    # is not simulated, the next restarts settled at the measured angle (as after a contact)
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
                     f"settled at the measured motor angle, {SETTLE_ROWS_S:g} s after each not "
                     "compared")
    note = "; ".join(notes)
    goal = JOINT_RATIO * motor  # joint-side motor angle -> shaft
    return DynamicData(t, cmds, y, output, keep, 1e-3,
                       out_scale=1.0 / JOINT_RATIO if output == "motor_angle_rad" else 1.0,
                       active=None if active.all() else active,
                       restart_goal_rad=goal, note=note)
