"""The emulated MX-28s through the unmodified dynamixel-sdk on a pty."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator

import dynamixel_sdk as sdk
import pytest

from sim.dynamixel_packets import build_v1
from sim.servo_emulator_bus import FaultConfig
from sim.servo_emulator_pty import PtyServoEmulator, make_bus_emulator
from teleop.config.hand import ObjectConfig

COMM_SUCCESS = sdk.COMM_SUCCESS
TIMEOUT_MS = 250.0


class Link:
    """An emulator on a pty and an SDK port open on it."""

    def __init__(self, protocol: int, **kw: object) -> None:
        self.emu = PtyServoEmulator(make_bus_emulator(protocol, **kw))  # type: ignore[arg-type]
        path = self.emu.start()
        self.port = sdk.PortHandler(path)
        self.port.baudrate = 57142  # non-standard: set it, then setupPort
        assert self.port.setupPort(0)
        self.ph = sdk.PacketHandler(float(protocol))
        # the stock 34 ms reply timeout is too tight on a loaded 2-core CI machine
        self.port.setPacketTimeout = lambda n: self.port.setPacketTimeoutMillis(TIMEOUT_MS)

    def close(self) -> None:
        self.port.closePort()
        self.emu.stop()


@pytest.fixture(params=[1, 2], ids=["p1", "p2"])
def link(request: pytest.FixtureRequest) -> Iterator[Link]:
    lk = Link(request.param, homes_counts=(100, -200, 300, 400), physics="simple")
    yield lk
    lk.close()


def test_ping_reads_model_number_and_unknown_id_times_out(link: Link) -> None:
    model, result, error = link.ph.ping(link.port, 1)
    assert (result, error) == (COMM_SUCCESS, 0)
    assert model == (29 if link.ph.getProtocolVersion() == 1.0 else 30)
    _, result, _ = link.ph.ping(link.port, 9)
    assert result == sdk.COMM_RX_TIMEOUT


def test_read_write_round_trip_and_multi_turn_position(link: Link) -> None:
    p1 = link.ph.getProtocolVersion() == 1.0
    goal, present, size = (30, 36, 2) if p1 else (116, 132, 4)
    pos, result, _ = link.ph.readTxRx(link.port, 2, present, size)
    assert result == COMM_SUCCESS
    assert int.from_bytes(bytes(pos), "little", signed=True) == -200  # home, negative
    assert link.ph.write1ByteTxRx(link.port, 2, 64 if not p1 else 24, 1) == (COMM_SUCCESS, 0)
    target = -260
    data = list(target.to_bytes(size, "little", signed=True))
    assert link.ph.writeTxRx(link.port, 2, goal, size, data) == (COMM_SUCCESS, 0)
    back, result, _ = link.ph.readTxRx(link.port, 2, goal, size)
    assert int.from_bytes(bytes(back), "little", signed=True) == target
    time.sleep(0.3)  # the servo moves its physics towards the goal
    pos, result, _ = link.ph.readTxRx(link.port, 2, present, size)
    now = int.from_bytes(bytes(pos), "little", signed=True)
    assert abs(now - target) < 5


def test_error_bits_for_bad_writes(link: Link) -> None:
    if link.ph.getProtocolVersion() == 1.0:
        # moving speed 2000 > 1023: range error (bit 3), register unchanged
        result, error = link.ph.write2ByteTxRx(link.port, 1, 32, 2000)
        assert (result, error) == (COMM_SUCCESS, 0x08)
        assert link.ph.read2ByteTxRx(link.port, 1, 32)[0] == 0
        # undefined instruction 0x30: instruction error (bit 6)
        pkt = [0] * 6
        pkt[2], pkt[3], pkt[4] = 1, 2, 0x30
        _, result, error = link.ph.txRxPacket(link.port, pkt)
        assert error == 0x40
    else:
        # present position is read-only: access error (7)
        result, error = link.ph.write4ByteTxRx(link.port, 1, 132, 5)
        assert (result, error) == (COMM_SUCCESS, 7)
        # EEPROM (operating mode) is locked while the torque is on
        link.ph.write1ByteTxRx(link.port, 1, 64, 1)
        assert link.ph.write1ByteTxRx(link.port, 1, 11, 3) == (COMM_SUCCESS, 7)


def test_reg_write_waits_for_action_and_sync_write_moves_all(link: Link) -> None:
    p1 = link.ph.getProtocolVersion() == 1.0
    led = 25 if p1 else 65
    assert link.ph.regWriteTxRx(link.port, 3, led, 1, [1]) == (COMM_SUCCESS, 0)
    assert link.ph.read1ByteTxRx(link.port, 3, led)[0] == 0
    assert link.ph.action(link.port, 3) == COMM_SUCCESS
    if not p1:  # the SDK does not wait for the status a 2.0 servo sends after ACTION
        link.port.setPacketTimeoutMillis(TIMEOUT_MS)
        rx, result = link.ph.rxPacket(link.port, False)
        assert (result, rx[4], rx[8]) == (COMM_SUCCESS, 3, 0)
    assert link.ph.read1ByteTxRx(link.port, 3, led)[0] == 1
    start, size = (30, 2) if p1 else (116, 4)
    group = sdk.GroupSyncWrite(link.port, link.ph, start, size)
    for i in (1, 2, 3, 4):
        group.addParam(i, list((1000 + i).to_bytes(size, "little")))
    assert group.txPacket() == COMM_SUCCESS
    time.sleep(0.01)
    for i in (1, 2, 3, 4):
        data, result, _ = link.ph.readTxRx(link.port, i, start, size)
        assert int.from_bytes(bytes(data), "little") == 1000 + i


def test_sync_read_p2_and_hand_built_bulk_read_p1(link: Link) -> None:
    if link.ph.getProtocolVersion() == 2.0:
        g = sdk.GroupSyncRead(link.port, link.ph, 132, 4)
        for i in (1, 2, 3, 4):
            g.addParam(i)
        assert g.txRxPacket() == COMM_SUCCESS
        got = [g.getData(i, 132, 4) for i in (1, 2, 3, 4)]
        assert got == [100, (-200) & 0xFFFFFFFF, 300, 400]
        return
    # BULK_READ 0x92 (GroupBulkRead is broken for 1.0 in dynamixel-sdk 4.1): build it by hand
    params = bytes([0x00, 2, 1, 36, 2, 4, 36])
    link.port.clearPort()
    link.port.writePort(build_v1(0xFE, 0x92, params))
    link.port.setPacketTimeoutMillis(200)
    replies = []
    for _ in range(2):
        rx, result = link.ph.rxPacket(link.port)
        assert result == COMM_SUCCESS
        replies.append((rx[2], int.from_bytes(bytes(rx[5:7]), "little", signed=True)))
    assert replies == [(1, 100), (4, 400)]


def test_status_return_level_1_answers_only_reads(link: Link) -> None:
    p1 = link.ph.getProtocolVersion() == 1.0
    level = 16 if p1 else 68
    assert link.ph.write1ByteTxOnly(link.port, 4, level, 1) == COMM_SUCCESS
    time.sleep(0.02)
    link.port.setPacketTimeout = lambda n: link.port.setPacketTimeoutMillis(40.0)
    result, _ = link.ph.write1ByteTxRx(link.port, 4, 25 if p1 else 65, 1)
    assert result == sdk.COMM_RX_TIMEOUT  # the write was done but not answered
    value, result, _ = link.ph.read1ByteTxRx(link.port, 4, 25 if p1 else 65)
    assert (value, result) == (1, COMM_SUCCESS)


@pytest.mark.parametrize("protocol", [1, 2])
def test_injected_overload_overheat_and_corruption(protocol: int) -> None:
    lk = Link(protocol, physics="simple",
              faults=FaultConfig(overload_ids=(2,), overheat_ids=(3,)))
    try:
        temp_addr = 43 if protocol == 1 else 146
        _, result, error = lk.ph.read1ByteTxRx(lk.port, 2, temp_addr)
        assert result == COMM_SUCCESS
        assert error == (0x20 if protocol == 1 else 0x80)  # overload bit / alert bit
        temp, _, error = lk.ph.read1ByteTxRx(lk.port, 3, temp_addr)
        assert temp == 85 and error == (0x04 if protocol == 1 else 0x80)
        if protocol == 2:
            hw, _, _ = lk.ph.read1ByteTxRx(lk.port, 2, 70)
            assert hw == 0x20
        lk.emu.bus.faults = FaultConfig(corrupt_rate=1.0)
        _, result, _ = lk.ph.ping(lk.port, 1)
        assert result == sdk.COMM_RX_CORRUPT
        lk.emu.bus.faults = FaultConfig(drop_rate=1.0)
        _, result, _ = lk.ph.ping(lk.port, 1)
        assert result == sdk.COMM_RX_TIMEOUT
        lk.emu.bus.faults = FaultConfig(latency_s=0.05)
        t0 = time.monotonic()
        _, result, _ = lk.ph.read1ByteTxRx(lk.port, 1, temp_addr)
        assert result == COMM_SUCCESS and time.monotonic() - t0 >= 0.05
        assert lk.emu.bus.counters.dropped >= 1 and lk.emu.bus.counters.corrupted >= 1
    finally:
        lk.close()


def test_finger_physics_load_rises_on_contact() -> None:
    """A finger servo closing on the object reports more load than one closing in free air."""
    loads = {}
    for kind in ("cylinder", "none"):
        lk = Link(1, ids=(1,), inversions=(1,), object_cfg=ObjectConfig(kind=kind))
        try:
            assert "finger model" in lk.emu.bus.physics.label
            assert lk.ph.write1ByteTxRx(lk.port, 1, 24, 1) == (COMM_SUCCESS, 0)
            assert lk.ph.write2ByteTxRx(lk.port, 1, 30, 350) == (COMM_SUCCESS, 0)  # 2.15 rad
            time.sleep(2.0)
            raw, r1, _ = lk.ph.read2ByteTxRx(lk.port, 1, 40)
            pos, r2, _ = lk.ph.read2ByteTxRx(lk.port, 1, 36)
            assert r1 == r2 == COMM_SUCCESS
            loads[kind] = (raw - 1024 if raw >= 1024 else -raw, pos)
        finally:
            lk.close()
    (load_obj, pos_obj), (load_free, pos_free) = loads["cylinder"], loads["none"]
    assert load_obj > 2.0 * load_free and load_obj > 150  # held against the object
    assert 150 < pos_obj < pos_free - 15  # the object stops the finger short of free motion


def test_cli_prints_path_and_exits_cleanly_on_ctrl_c() -> None:
    proc = subprocess.Popen([sys.executable, "-m", "teleop.cli", "servo-emulator",
                             "--physics", "simple"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        path = proc.stdout.readline().strip()
        assert os.path.exists(path)
        port = sdk.PortHandler(path)
        port.baudrate = 57142
        port.setupPort(0)
        port.setPacketTimeout = lambda n: port.setPacketTimeoutMillis(TIMEOUT_MS)
        model, result, _ = sdk.PacketHandler(1.0).ping(port, 3)
        port.closePort()
        assert (model, result) == (29, COMM_SUCCESS)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=10) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


@pytest.mark.parametrize(("argv", "names"), [
    (["--ids", "1,1"], "--ids"),
    (["--ids", "1,2", "--overload-id", "7"], "--overload-id 7"),  # no such servo
    (["--overheat-id", "9"], "--overheat-id 9"),
    (["--effect", "warp_drive=1"], "warp_drive"),
    (["--physics", "simple", "--effect", "dead_time=0.1"], "--effect dead_time=0.1"),
])
def test_cli_rejects_bad_options_in_one_line(argv: list[str], names: str) -> None:
    out = subprocess.run([sys.executable, "-m", "teleop.cli", "servo-emulator", *argv,
                          "--duration", "0.1"], capture_output=True, text=True, timeout=30)
    assert out.returncode == 2
    assert out.stderr.strip().count("\n") == 0 and names in out.stderr


def test_an_effect_given_to_the_emulator_acts_in_its_finger_physics() -> None:
    """--effect reaches the finger model: a 0.1 s dead time shifts a closing move by 0.1 s."""
    from sim.servo_emulator_physics import FingerServoPhysics, ServoDrive
    from teleop.effects import EffectSet

    paths = {}
    for delay in (0.0, 0.1):
        phys = FingerServoPhysics([0.0], [1], None, EffectSet(dead_time=delay))
        assert ("dead_time=0.1" in phys.label) == (delay > 0)
        path = []
        for _ in range(8):
            phys.step([ServoDrive(True, 2.0, 5.0, 1.0)], 1e-3, steps=50)  # batches of 50 ms
            path.append(phys.sense()[0].angle_rad)
        paths[delay] = path
    assert paths[0.0][1] > 0.03 and paths[0.1][1] == 0.0  # still waiting at 0.1 s
    assert paths[0.1][2:] == pytest.approx(paths[0.0][:-2], abs=2e-3)  # the same move, later
