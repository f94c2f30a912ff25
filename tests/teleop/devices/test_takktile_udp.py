"""The reflex-takktile backend over real UDP sockets against `teleop hand-emulator`."""

from __future__ import annotations

import subprocess
import sys
import time
from typing import Any

import pytest

from services.bench import free_port
from sim.hand_emulator_bench import start_board_process, stop_board_process
from teleop.config import load_config
from teleop.devices.reflex_takktile import TakkTileHand, build_takktile_hand


def hand_on(port: int, *overrides: str) -> TakkTileHand:
    cfg = load_config(None, ["hand.backend=reflex-takktile", f"hand.takktile.port={port}",
                             *overrides])
    return build_takktile_hand(cfg.hand)


@pytest.mark.network
@pytest.mark.slow
def test_a_silent_board_is_stale_after_4_of_its_periods_over_udp() -> None:
    """Every read is stale exactly when the board has been quiet for 4 periods (100 ms at
    40 Hz); the board goes silent after 2 s and the hand notices at its next tick.  The
    wall-clock detection delay beyond 100 ms is this process's scheduling, printed."""
    board, port = start_board_process(("--silent-after", "2"))
    hand = hand_on(port, "hand.takktile.network=unicast", "hand.takktile.address=127.0.0.1")
    reads: list[tuple[float, bool]] = []  # (quiet s, stale) per read
    try:
        hand.start()
        t_end = time.monotonic() + 8.0
        while time.monotonic() < t_end:
            time.sleep(0.025)  # the hand service's 40 Hz tick
            r = hand.read(0.0)
            assert hand.last_valid_s is not None
            reads.append((time.monotonic() - hand.last_valid_s, r.stale))
            if r.stale and len(reads) > 10 and all(s for _, s in reads[-5:]):
                break  # silent for good
    finally:
        hand.close()
        stop_board_process(board)
    threshold = 4 * hand.period_s
    assert threshold == pytest.approx(0.1, rel=0.05)  # the board ran free at 40 Hz
    for quiet, stale in reads:
        if abs(quiet - threshold) > 0.005:  # (a read on the boundary may go either way)
            assert stale == (quiet > threshold), (quiet, stale)
    assert reads[-1][1]  # the silence was noticed
    i0 = len(reads) - 1
    while i0 > 0 and reads[i0 - 1][1]:
        i0 -= 1  # the start of the final stale run
    print(f"silent board noticed {reads[i0][0] * 1e3:.0f} ms after its last packet; stale "
          f"reads while it was still sending (scheduling stalls): "
          f"{sum(s for _, s in reads[:i0])} of {i0}")


def start_multicast_board(port: int) -> Any:
    proc = subprocess.Popen([sys.executable, "-m", "teleop.cli", "hand-emulator", "--multicast",
                             "--address", "224.0.0.124", "--port", str(port)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    if not proc.stdout.readline().strip():
        _, err = proc.communicate(timeout=10)
        pytest.skip(f"this host refuses multicast on loopback: {err.strip()[-200:]}")
    return proc


@pytest.mark.network
def test_multicast_224_0_0_124_where_the_host_allows() -> None:
    port = free_port()
    board = start_multicast_board(port)
    hand = hand_on(port, "hand.takktile.multicast_loopback=true")
    try:
        hand.start()
        for _ in range(20):
            time.sleep(0.025)
            r = hand.read(0.0)
        counts = hand.rx.counts()
    finally:
        hand.close()
        stop_board_process(board)
    assert counts.accepted >= 15 and counts.rejected == 0  # its own commands are not counted
    assert not r.stale
    assert max(abs(p) for f in r.fingers for p in f.pressure) < 15  # resting offsets gone


@pytest.mark.network
@pytest.mark.slow
def test_injected_packet_faults_are_dropped_by_reason_and_the_hand_carries_on() -> None:
    board, port = start_board_process(("--truncate-rate", "0.1", "--bad-magic-rate", "0.1",
                                       "--late-rate", "0.1", "--late-ms", "80", "--loss", "0.1",
                                       "--seed", "3"))
    hand = hand_on(port, "hand.takktile.network=unicast", "hand.takktile.address=127.0.0.1")
    try:
        hand.start()
        stale = 0
        for _ in range(80):  # 2 s at the hand's 40 Hz
            time.sleep(0.025)
            stale += hand.read(0.0).stale
        counts = hand.rx.counts()
    finally:
        hand.close()
        stop_board_process(board)
    assert counts.count("bad_length") > 0 and counts.count("bad_magic") > 0
    assert counts.count("stale_time") > 0  # a late packet overtaken by newer ones
    assert counts.accepted > 40
    print(f"accepted {counts.accepted}, dropped {dict(counts.by_reason)}, stale reads {stale}")
