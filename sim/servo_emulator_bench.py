"""``teleop bench servo``: bus cycle time for four servos over the emulator's pty.

One cycle is what the hand does per control tick: a synchronised goal write to four servos
plus the state reads (Protocol 1.0: one READ per servo, or one BULK_READ; Protocol 2.0: two
SYNC_READs: the state block and the hardware error status).  The
emulator runs as a separate process (``teleop servo-emulator``), so the figures include the
real pty round trips and dynamixel-sdk's own packet handling, but not the serial line's
transmission time; that is reported separately for the ReFlex's 57142 baud.
"""

from __future__ import annotations

import subprocess
import sys
import time
from typing import Any

import numpy as np

from teleop.devices import dynamixel_tables as T

IDS = (1, 2, 3, 4)


def start_emulator_process(protocol: int, extra: tuple[str, ...] = ()) -> tuple[Any, str]:
    """Start ``teleop servo-emulator`` in a subprocess; returns (process, pty path)."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "teleop.cli", "servo-emulator", "--protocol", str(protocol),
         *extra], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    assert proc.stdout is not None
    path = proc.stdout.readline().strip()
    if not path:
        proc.kill()
        proc.wait(timeout=5)
        raise RuntimeError("servo emulator did not start")
    return proc, path


def stop_emulator_process(proc: Any) -> None:
    """Stop an emulator started by :func:`start_emulator_process`."""
    proc.terminate()
    try:
        proc.wait(timeout=5)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(timeout=5)
    if proc.stdout is not None:
        proc.stdout.close()


def wire_bytes_per_cycle(protocol: int, n: int = len(IDS), bulk: bool = False) -> int:
    """Bytes on the serial line per cycle (instruction and status packets)."""
    if protocol == 1 and bulk:
        return 8 + n * (1 + T.P1_GOAL_LEN) + (7 + 3 * n) + n * (6 + T.P1_STATE_LEN)
    if protocol == 1:
        sync_write = 8 + n * (1 + T.P1_GOAL_LEN)
        reads = n * (8 + 6 + T.P1_STATE_LEN)
        return sync_write + reads
    sync_write = 14 + n * (1 + T.P2_GOAL_LEN)
    sync_reads = (14 + n) + n * (11 + T.P2_STATE_LEN) + (14 + n) + n * (11 + 1)
    return sync_write + sync_reads


def _cycle_times_us(protocol: int, cycles: int, bulk: bool = False) -> tuple[np.ndarray, int]:
    from teleop.devices.dynamixel_bus import DynamixelBus, Goal

    proc, path = start_emulator_process(protocol)
    bus = DynamixelBus(path, 57142 if protocol == 1 else 57600, float(protocol), IDS,
                       retries=2, timeout_s=0.05, bulk_read=bulk)
    try:
        bus.open()
        for i in IDS:
            bus.write(i, "torque_enable", 1)
        times = np.empty(cycles)
        for k in range(cycles + 50):
            goals = {i: Goal(100 + (k % 50), 0) for i in IDS}
            t0 = time.perf_counter()
            bus.write_goals(goals)
            bus.read_states()
            if k >= 50:
                times[k - 50] = (time.perf_counter() - t0) * 1e6
        return times, bus.failed_attempts
    finally:
        bus.close()
        stop_emulator_process(proc)


#: a bus cycle longer than this counts as a stall (``*_stalls``, beside every p99 and max):
#: the services' watchdog timeout, most of the hand's 25 ms period
STALL_US = 20_000.0


def bench_servo(cycles: int = 1000) -> dict[str, float]:
    """Cycle-time figures for four servos: Protocol 1.0 (single READs and BULK_READ), 2.0."""
    out: dict[str, float] = {"servos": float(len(IDS)), "cycles": float(cycles)}
    for protocol, bulk, pre in ((1, False, "p1_"), (1, True, "p1_bulk_"), (2, False, "p2_")):
        t, failed = _cycle_times_us(protocol, cycles, bulk)
        out[pre + "p50_us"] = float(np.percentile(t, 50))
        out[pre + "p99_us"] = float(np.percentile(t, 99))
        out[pre + "max_us"] = float(t.max())
        out[pre + "stalls"] = float(np.count_nonzero(t > STALL_US))
        out[pre + "cycles_per_s"] = float(1e6 / t.mean())
        out[pre + "failed_attempts"] = float(failed)
        nbytes = wire_bytes_per_cycle(protocol, bulk=bulk)
        out[pre + "wire_bytes_per_cycle"] = float(nbytes)
        baud = 57142 if protocol == 1 else 57600
        out[pre + f"wire_time_at_{baud}_baud_us"] = nbytes * 10 / baud * 1e6
    # the headline figures: the ReFlex's own arrangement (Protocol 1.0, one READ per servo)
    for key in ("p50_us", "p99_us", "max_us", "stalls", "cycles_per_s"):
        out[key] = out["p1_" + key]
    return out
