"""``teleop bench takktile``: the brain-board packet round trip against ``teleop hand-emulator``.

The emulator runs as its own process on loopback UDP; the PC side is the backend's
:class:`~teleop.devices.brain_board_link.BoardLink` and
:class:`~teleop.devices.brain_board_packets.StateReceiver`.  Figures:

* ``command_to_effect_ms`` p50/p99/max: a targets packet sent (finger 1 stepped by 0.3 rad)
  until the first state packet whose servo angle has moved towards it by more than 2 counts:
  the round trip a controller sees (UDP both ways, the board's 25 ms state schedule, the
  servo starting to move);
* ``state_interval_ms`` p50/p99/max and ``state_rate_hz``: arrival of valid state packets on
  the PC clock, fingers free (40 Hz on the board);
* ``decode_us``: validating one 202-byte state packet (the PC's cost per packet).
"""

from __future__ import annotations

import subprocess
import sys
import time
from typing import Any

import numpy as np

from teleop.devices import takktile_units as U
from teleop.devices.brain_board_link import BoardLink
from teleop.devices.brain_board_packets import StateReceiver, encode_modes, encode_targets


def start_board_process(extra: tuple[str, ...] = ()) -> tuple[Any, int]:
    """Start ``teleop hand-emulator --port 0`` (unicast 127.0.0.1); returns (process, port)."""
    proc = subprocess.Popen([sys.executable, "-m", "teleop.cli", "hand-emulator", "--port", "0",
                             *extra], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                            text=True)
    assert proc.stdout is not None
    line = proc.stdout.readline().strip()
    if ":" not in line:
        proc.kill()
        proc.wait(timeout=5)
        raise RuntimeError("hand emulator did not start")
    return proc, int(line.rsplit(":", 1)[1])


def stop_board_process(proc: Any) -> int:
    """Stop an emulator started by :func:`start_board_process` (SIGTERM); its exit status."""
    proc.terminate()
    try:
        status = proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
        status = proc.wait(timeout=5)
    if proc.stdout is not None:
        proc.stdout.close()
    return int(status)


def _pct(prefix: str, values: list[float]) -> dict[str, float]:
    a = np.asarray(values, dtype=float)
    if a.size == 0:
        return {f"{prefix}_n": 0.0}
    return {f"{prefix}_p50": float(np.percentile(a, 50)), f"{prefix}_p99":
            float(np.percentile(a, 99)), f"{prefix}_max": float(a.max()),
            f"{prefix}_n": float(a.size)}


def bench_takktile(steps: int = 30, step_s: float = 0.4) -> dict[str, float]:
    """Round-trip figures over ``steps`` finger steps ``step_s`` apart (~``steps * step_s`` s)."""
    proc, port = start_board_process()
    link = BoardLink("unicast", "127.0.0.1", port)
    rx = StateReceiver()
    arrivals: list[float] = []
    effects: list[float] = []
    last: list[int] = [0]  # finger 1's servo angle in the latest state
    try:
        link.open()
        link.send(encode_modes((2, 2, 2, 2)))

        def states(until: float) -> list[Any]:
            got = []
            while time.monotonic() < until:
                for data in link.receive():
                    s = rx.accept(data)
                    if s is not None:
                        arrivals.append(time.monotonic())
                        last[0] = U.signed_counts(s.dxl_angle[0])
                        got.append(s)
                time.sleep(0.0005)
            return got

        states(time.monotonic() + 0.5)
        for k in range(steps):
            goal_rad = 0.3 if k % 2 == 0 else 0.0
            base = last[0]  # the angle before the command
            sent = time.monotonic()
            link.send(encode_targets((U.raw_goal(goal_rad, 1, 0.0, 1.42), 0,
                                      U.raw_goal(0.0, 1, 0.0, 1.42), 0)))
            end = sent + step_s
            while time.monotonic() < end:
                for s in states(time.monotonic() + 0.001):
                    a = U.signed_counts(s.dxl_angle[0])
                    moved = (a - base) if goal_rad > 0 else (base - a)
                    if moved > 2 and len(effects) <= k:
                        effects.append((arrivals[-1] - sent) * 1e3)
    finally:
        link.close()
        stop_board_process(proc)
    return _figures(arrivals, effects, rx)


def _figures(arrivals: list[float], effects: list[float], rx: StateReceiver) -> dict[str, float]:
    from teleop.devices.brain_board_packets import BoardState, encode_state

    intervals = list(np.diff(arrivals) * 1e3) if len(arrivals) > 1 else []
    packet = encode_state(BoardState((1, 0, 0, 0), 1, (0,) * 38, (0,) * 38, (0, 0, 0),
                                     (0,) * 4, (0,) * 4, (0,) * 4, (0,) * 4, (0,) * 4,
                                     (0,) * 4))  # type: ignore[arg-type]
    n = 20000
    r = StateReceiver()
    t0 = time.perf_counter()
    for _ in range(n):
        r.last_time_us = None
        r.accept(packet)
    decode_us = (time.perf_counter() - t0) / n * 1e6
    c = rx.counts()
    out: dict[str, float] = {"states": float(c.accepted), "dropped": float(c.rejected)}
    out |= _pct("command_to_effect_ms", effects)
    out |= _pct("state_interval_ms", intervals)
    span = arrivals[-1] - arrivals[0] if len(arrivals) > 1 else float("nan")
    out["state_rate_hz"] = (len(arrivals) - 1) / span if span == span and span > 0 else 0.0
    out["decode_us"] = decode_us
    return out
