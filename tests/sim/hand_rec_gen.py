"""An independent generator of ``teleop up --record`` style hand recordings for the diagnose
tests: the simulated hand behind the hand-backend interface (:class:`sim.sim_hand.SimHand`:
the whole hand stepped at 1 kHz, encoders quantised and noisy as the driver reads them), finger
parameters a few percent off the calibrated ones, set-points held between irregular 40 Hz
ticks, columns named as the hand service names them.  The diagnosis never sees these values.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from sim.hand import default_hand_params
from sim.sim_hand import SimHand
from teleop.config import load_config
from teleop.effects import EffectSet
from teleop.messages import HandCommand, Header
from teleop.recording import Recording, write_recording

OFF_NOMINAL = {"units_per_n": 1.04, "motor_coulomb_units": 0.95, "k_base_nm_per_rad": 1.03}


def setpoints(rng: np.random.Generator, t: np.ndarray, max_rad: float = 2.5) -> np.ndarray:
    """Joint set-points: random holds and ramps between 0 and ``max_rad``, as a grasp cycle."""
    out = np.zeros(len(t))
    level, target, t_next = 0.0, 0.0, 0.0
    for i, ti in enumerate(t):
        if ti >= t_next:
            target = float(rng.uniform(0.0, max_rad))
            t_next = ti + float(rng.uniform(0.6, 1.6))
        level += np.clip(target - level, -0.08, 0.08) if rng.random() < 0.5 else target - level
        out[i] = level
    return out


def hand_recording(path: Path, seconds: float, seed: int, effects: EffectSet = EffectSet(),
                   obj: str = "none", max_rad: float = 2.5, late_s: float = 0.0,
                   clock_columns: bool = False, load_column: bool = False) -> Path:
    """Write a hand recording (finger 1 driven; fingers 2 and 3 follow at lower set-points).

    ``late_s``: each tick reads the hand up to that late after its deadline ``t_s`` (uniform;
    one tick in ten up to 4x that, as a loaded host's loop catching up) and writes the
    set-points 2-15 ms after the read; ``clock_columns`` records those times as the hand
    service does (``read_t_s``, ``write_t_s``); ``load_column`` the servos' present load
    (``motor_load_units_fN``, as every hand service recording has it)."""
    rng = np.random.default_rng(seed)
    cfg = load_config(None, [f"hand.sim.object.kind={obj}", "hand.sim.noise=true"])
    hand = SimHand(cfg.hand, seed=seed, effects=effects)
    fp = hand.params.finger
    hand.params = default_hand_params(replace(fp, **{k: getattr(fp, k) * f
                                                     for k, f in OFF_NOMINAL.items()}))
    hand.start()
    dt = np.full(int(seconds * 40), 0.025) + rng.uniform(-0.002, 0.002, int(seconds * 40))
    t = np.cumsum(dt) - dt[0]
    sp = setpoints(rng, t, max_rad)
    cols: dict[str, list[float]] = {k: [] for k in (
        "t_s", *(f"{n}_f{i}" for n in ("proximal_angle_rad", "motor_angle_rad", "contacts",
                                       "setpoint_rad") for i in (1, 2, 3)),
        *(("read_t_s", "write_t_s") if clock_columns else ()),
        *((f"motor_load_units_f{i}" for i in (1, 2, 3)) if load_column else ()))}
    n = len(t)
    late = late_s * rng.uniform(0.0, 1.0, n) * np.where(rng.random(n) < 0.1, 4.0, 1.0)
    took = rng.uniform(0.002, 0.015, n) if late_s > 0 else np.zeros(n)
    read_t, write_t = np.empty(n), np.empty(n)
    done = -np.inf
    for i in range(n):  # one tick after the other: a late tick delays the next one's read
        read_t[i] = max(t[i] + late[i], done + 1e-4)
        write_t[i] = done = read_t[i] + took[i]
    for ti, s, rt, wt in zip(t, sp, read_t, write_t, strict=True):
        r = hand.read(float(rt))
        sps = (float(s), 0.6 * float(s), 0.3 * float(s))
        if wt > rt:
            hand.read(float(wt))  # the physics runs on until the set-points are written
        hand.apply(HandCommand(Header(0, float(ti), 0.0), sps, 0.0))
        cols["t_s"].append(float(ti) + 3.0)
        if clock_columns:
            cols["read_t_s"].append(float(rt) + 3.0)
            cols["write_t_s"].append(float(wt) + 3.0)
        for i, f in enumerate(r.fingers, 1):
            cols[f"proximal_angle_rad_f{i}"].append(f.proximal_rad)
            cols[f"motor_angle_rad_f{i}"].append(f.motor_angle_rad)
            cols[f"contacts_f{i}"].append(float(sum(f.contact)))
            cols[f"setpoint_rad_f{i}"].append(sps[i - 1])
            if load_column:
                cols[f"motor_load_units_f{i}"].append(round(f.load_units))
    write_recording(path, Recording.from_columns(cols, meta=(("role", "hand"),
                                                             ("rate_hz", "40"))))
    return path


def flag_moving(rec: Recording, n: int = 3, rows: int = 6) -> Recording:
    """``rec`` with ``rows`` rows flagged as contact (``contacts_f1``) before each of the
    ``n`` fastest moves of finger 1's motor, as the dynamixel driver flags free-air rows from
    the load: the simulation restarts there, mid-motion."""
    data = rec.data.copy()
    col = rec.columns.index("contacts_f1")
    speed = np.abs(np.gradient(rec.column("motor_angle_rad_f1")))
    speed[:20] = speed[-10:] = 0.0  # not at the ends
    for _ in range(n):
        i = int(np.argmax(speed))
        data[i - rows:i, col] = 1.0
        speed[max(0, i - 30):i + 30] = 0.0
    return Recording(rec.columns, data, rec.meta, source=rec.source)
