"""A hand recording's real read and write times (``read_t_s``, ``write_t_s``) and the delay line
across an excluded stretch, judged against an independent generator
(`tests/sim/hand_rec_gen.py`: the simulated hand at 1 kHz, finger parameters off nominal,
sensor noise): what the finger model simulates must follow what the hand really did."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hand_rec_gen import flag_moving, hand_recording  # tests/sim/hand_rec_gen.py

import sim.finger_dynamic as fd
from sim.finger_diagnose import default_finger_params
from sim.finger_hand_rec import hand_finger_data
from teleop.effects import EffectSet
from teleop.errors import RecordingError
from teleop.recording import Recording, read_recording


def _without(rec: Recording, *names: str) -> Recording:
    keep = [i for i, c in enumerate(rec.columns) if c not in names]
    return Recording(tuple(rec.columns[i] for i in keep), rec.data[:, keep], rec.meta,
                     source=rec.source)


def _nrmse(rec: Recording, eff: EffectSet = EffectSet()) -> float:
    """The calibrated finger (the generator's is 3-5 % off) simulated from the recording."""
    data = hand_finger_data(rec, 1)
    y = fd.simulate_dynamic(default_finger_params(), eff, data, 2e-3, "compiled")[data.keep]
    ym = data.y[data.keep]
    return float(np.sqrt(np.mean((y - ym) ** 2)) / np.std(ym))


def test_the_simulation_follows_the_recorded_read_and_write_times(tmp_path: Path) -> None:
    """A hand loop that reads up to 50 ms late (one tick in ten up to 200 ms, as a loaded host)
    and writes 2-15 ms after reading: ``t_s`` (the deadline) is then wrong by that much.  On
    the recorded read/write times the calibrated finger fits as well as a punctual loop's
    recording (measured NRMSE 0.0046 punctual, 0.0049 late); on the deadlines 0.087 (19x).
    Mutant: the adapter ignoring the two columns fails."""
    punctual = read_recording(hand_recording(tmp_path / "a.csv", 10.0, seed=6))
    late = read_recording(hand_recording(tmp_path / "b.csv", 10.0, seed=6, late_s=0.05,
                                         clock_columns=True))
    base = _nrmse(punctual)
    assert _nrmse(late) < 1.5 * base, (_nrmse(late), base)
    assert _nrmse(_without(late, "read_t_s", "write_t_s")) > 5.0 * base  # the deadlines
    assert "read_t_s" in hand_finger_data(punctual, 1).note  # said when the columns are absent


def test_bad_read_times_are_one_line(tmp_path: Path) -> None:
    rec = read_recording(hand_recording(tmp_path / "a.csv", 2.0, seed=1, late_s=0.01,
                                        clock_columns=True))
    data = rec.data.copy()
    data[30, rec.columns.index("read_t_s")] = np.nan
    with pytest.raises(RecordingError, match=r"'read_t_s' .* row 31"):
        hand_finger_data(Recording(rec.columns, data, rec.meta, source="x.csv"), 1)


@pytest.mark.parametrize("seed", [6, 9])
def test_a_restart_keeps_the_commands_still_in_the_delay_line(seed: int, tmp_path: Path) -> None:
    """A 0.15 s command delay in the hand, free air, but rows flagged as contact (the dynamixel
    driver estimates contact from load and flags free-air rows too): every segment restarts
    after a flagged stretch.  The delayed servo still executes the set-points written in the
    0.15 s before the restart; the simulation must too (``_primed``), or the delay that fits
    best is not the true one.  Measured rms (rad) over the delay grid 0.05-0.25 s, with the
    commands kept: seed 6 minimum 0.050 at 0.15 s, seed 9 0.026 at 0.15 s; without (the
    mutant, no priming in the compiled kernel) seed 9's minimum moves to 0.05 s (0.105; 0.085
    at 0.15 s)."""
    eff = EffectSet(dead_time=0.15)
    rec = read_recording(hand_recording(tmp_path / "a.csv", 10.0, seed=seed, effects=eff,
                                        late_s=0.01, clock_columns=True))
    data = rec.data.copy()
    col = rec.columns.index("contacts_f1")
    for start in (60, 140, 220, 300):
        data[start:start + 6, col] = 1.0
    d = hand_finger_data(Recording(rec.columns, data, rec.meta, source=rec.source), 1)
    assert d.active is not None and np.sum(d.active[1:] & ~d.active[:-1]) == 4
    p = default_finger_params()
    grid = (0.05, 0.1, 0.125, 0.15, 0.175, 0.2, 0.25)
    rms = []
    for delay in grid:
        r = (fd.simulate_dynamic(p, EffectSet(dead_time=delay), d, 2e-3, "compiled") - d.y)
        rms.append(float(np.sqrt(np.mean(r[d.keep] ** 2))))
    assert grid[int(np.argmin(rms))] == 0.15, dict(zip(grid, rms, strict=True))


@pytest.mark.parametrize("seed", [1, 3])
def test_a_restart_starts_at_the_measured_angle_and_load(seed: int, tmp_path: Path) -> None:
    """A segment restarting mid-motion (rows flagged before the three fastest moves, a 0.15 s
    delay in the hand) starts at the measured motor angle, the finger at rest on it and the
    servo's effort the recorded load: the calibrated finger then fits as well as without the
    flags (measured rms 0.0065 / 0.0026 rad flagged, 0.0072 / 0.0023 not).  Mutant: settled
    from rest under the measured angle as the goal (the old restart), the finger stopped 0.03-
    0.17 rad short of it and the rms was 4-11x (a sensor offset at its bound stood in for it
    on the dynamixel proof's recordings); holding instead of the recorded load: 0.013 / 0.018."""
    eff = EffectSet(dead_time=0.15)
    rec = read_recording(hand_recording(tmp_path / "a.csv", 4.0, seed=seed, effects=eff,
                                        late_s=0.01, clock_columns=True, load_column=True))
    p = default_finger_params()

    def rms(r: Recording) -> float:
        d = hand_finger_data(r, 1)
        y = fd.simulate_dynamic(p, eff, d, 2e-3, "compiled")
        return float(np.sqrt(np.mean((y - d.y)[d.keep] ** 2)))

    cut = flag_moving(rec)
    d = hand_finger_data(cut, 1)
    assert d.active is not None
    starts = np.flatnonzero(d.active[1:] & ~d.active[:-1]) + 1
    assert len(starts) == 3
    y = fd.simulate_dynamic(p, eff, d, 2e-3, "compiled")
    np.testing.assert_allclose(y[starts], d.y[starts], atol=1e-9)  # no settle error
    flagged = rms(cut)
    assert flagged < 1.5 * rms(rec) + 1e-3, (flagged, rms(rec))
    assert rms(_without(cut, "motor_load_units_f1")) > 1.5 * flagged  # the load matters
