"""Fault-suite figures: pure functions over time series, and the malformed-payload generator.

The runner (:mod:`services.faults`) injects a fault into a lockstep run and compares it with
a fault-free baseline of the same config and seed; these functions turn the two runs into
the figures ``teleop faults`` reports:

* :func:`recovery_time_s`: after the fault ends, how long until the hand's applied set-point
  tracks the baseline's (which follows the trigger) within ``tol_rad`` and stays there for
  ``settle_s``;
* :func:`energy_violations`: samples at which the energy balance margin went negative;
* :func:`held_still`: whether a set-point stayed put over a window (the hand never moves on
  missing or invalid data);
* :func:`malformed_payload`: the i-th payload of a flood, each one invalid for a known
  reason (random bytes, truncation, NaN, out-of-range, wrong kind, bad version, oversize,
  replayed sequence number, an energy total that jumps).
"""

from __future__ import annotations

import math
import random

import msgpack
import numpy as np

from teleop.messages import (
    N_PRESSURE,
    SCHEMA_VERSION,
    FingerState,
    ForceCommand,
    HandCommand,
    HandState,
    Header,
    MasterState,
    Message,
)

Array = np.ndarray

#: Kinds of malformed payloads, cycled through by :func:`malformed_payload`, with the
#: rejection reason each one must get at the receiver.
FLOOD_KINDS: tuple[tuple[str, str], ...] = (
    ("random_bytes", "*"),  # garbage: malformed / bad_shape / unknown_kind ...
    ("truncated", "malformed"),
    ("nan_field", "not_finite"),
    ("out_of_range", "out_of_range"),
    ("wrong_kind", "unexpected_kind"),
    ("bad_version", "bad_version"),
    ("oversize", "too_large"),
    ("bad_type", "bad_type"),
    ("not_array", "bad_shape"),
    ("replayed_seq", "stale_seq"),
    ("energy_jump", "energy_jump"),
)

_KIND_OF_SIGNAL = {"master_state": 1, "force_command": 2, "hand_command": 3, "hand_state": 4}


def _finger_wire(angle: float) -> list[object]:
    return [angle, 0.0, angle, 0.0, [0.0] * 9, [False] * 9]


def _valid_message(signal: str, seq: int, energy_j: float) -> Message:
    """A valid message for ``signal`` asking for a large motion (set-points 2.5 rad)."""
    h = Header(seq=seq, t_s=1.0, energy_total_j=energy_j)
    if signal == "master_state":
        return MasterState(h, 0.01, 0.0)
    if signal == "force_command":
        return ForceCommand(h, 1.0)
    if signal == "hand_command":
        return HandCommand(h, (2.5, 2.5, 2.5), 0.0)
    f = FingerState(2.5, 0.0, 2.5, 0.0, (0.0,) * N_PRESSURE, (False,) * N_PRESSURE)
    return HandState(h, (f, f, f), 0.0)


def _valid_wire(signal: str, seq: int, energy_j: float) -> list[object]:
    """A well-formed wire array for ``signal`` (before corruption), of the present schema."""
    from teleop.transport.codec import encode

    wire = msgpack.unpackb(encode(_valid_message(signal, seq, energy_j)), raw=False)
    assert wire[0] == _KIND_OF_SIGNAL[signal] and wire[1] == SCHEMA_VERSION
    return list(wire)


def malformed_payload(i: int, signal: str, seed: int = 0) -> tuple[str, bytes]:
    """``(kind, payload)``: the ``i``-th flood payload aimed at ``signal``; never valid.

    Every payload that decodes at all asks for a large motion (set-points 2.5 rad, full
    trigger), so a receiver that let one through would visibly move the hand.
    """
    kind = FLOOD_KINDS[i % len(FLOOD_KINDS)][0]
    rng = random.Random(seed * 1_000_003 + i)
    big_seq = 2**40 + i  # above any real sequence number: only the energy check stops it
    wire = _valid_wire(signal, big_seq, 0.0)
    if kind == "random_bytes":
        data = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 64)))
        try:  # a random string that happens to be a valid message is astronomically rare
            msgpack.unpackb(data)
        except Exception:
            return kind, data
        return kind, b"\xc1" + data  # 0xc1 is never valid msgpack
    if kind == "truncated":
        full = msgpack.packb(wire, use_bin_type=True)
        return kind, full[: rng.randrange(1, len(full) - 1)]
    if kind == "nan_field":
        wire[3] = math.nan
    elif kind == "out_of_range":
        wire[5] = [1e3, 1e3, 1e3] if signal == "hand_command" else 1e3
        if signal == "hand_state":
            wire[5] = [_finger_wire(1e3) for _ in range(3)]
    elif kind == "wrong_kind":
        wire[0] = 2 if signal != "force_command" else 3
    elif kind == "bad_version":
        wire[1] = SCHEMA_VERSION + 1
    elif kind == "oversize":
        return kind, msgpack.packb([*wire, b"\0" * 4096], use_bin_type=True)
    elif kind == "bad_type":
        wire[4] = "lots"
    elif kind == "not_array":
        return kind, msgpack.packb(rng.randrange(1 << 30))
    elif kind == "replayed_seq":
        wire[2] = 0  # a replay of a captured first message: its seq is long past
    elif kind == "energy_jump":
        wire[4] = 1.0e9  # a cumulative energy total no real sender reaches in one message
    return kind, msgpack.packb(wire, use_bin_type=True)


def recovery_time_s(t_s: Array, setpoint_rad: Array, reference_rad: Array, t_end_s: float,
                    tol_rad: float = 0.05, settle_s: float = 0.25) -> float:
    """Time after ``t_end_s`` until ``setpoint_rad`` stays within ``tol_rad`` of
    ``reference_rad`` (all fingers) for ``settle_s`` (or to the end of the run); ``inf``
    if it never does.  Rows are samples; NaN rows count as not tracking."""
    err = np.nanmax(np.abs(np.asarray(setpoint_rad) - np.asarray(reference_rad)), axis=1) \
        if np.asarray(setpoint_rad).ndim == 2 else np.abs(setpoint_rad - reference_rad)
    ok = np.isfinite(err) & (err <= tol_rad)
    idx = np.nonzero(t_s >= t_end_s - 1e-12)[0]
    if idx.size == 0:
        return math.inf
    bad_after = idx[~ok[idx]]
    # candidate starts: t_end itself, and just after each non-tracking sample
    starts = [int(idx[0])] + [int(b) + 1 for b in bad_after if b + 1 < len(t_s)]
    for s in starts:
        if not ok[s]:
            continue
        nxt = bad_after[bad_after > s]
        until = t_s[nxt[0]] if nxt.size else math.inf
        if until - t_s[s] >= settle_s or not nxt.size:
            return max(0.0, float(t_s[s] - t_end_s))
    return math.inf


def energy_violations(margin_j: Array, tol_j: float = 1e-9) -> int:
    """Samples at which delivered energy exceeded the bound (margin below ``-tol_j``)."""
    m = np.asarray(margin_j, dtype=float)
    return int(np.count_nonzero(~np.isfinite(m) | (m < -tol_j)))


def held_still(t_s: Array, setpoint_rad: Array, t0_s: float, t1_s: float,
               tol_rad: float = 1e-9) -> bool:
    """Whether ``setpoint_rad`` did not move over ``[t0_s, t1_s]`` (True for an empty window)."""
    sel = (t_s >= t0_s) & (t_s <= t1_s)
    if not np.any(sel):
        return True
    w = np.asarray(setpoint_rad)[sel]
    return bool(np.all(np.isfinite(w)) and np.max(np.ptp(w, axis=0)) <= tol_rad)


__all__ = ["FLOOD_KINDS", "energy_violations", "held_still", "malformed_payload",
           "recovery_time_s"]
