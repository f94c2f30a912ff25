"""DynamixelBus through the unmodified dynamixel-sdk against the emulated servos on a pty."""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator

import pytest

from sim.servo_emulator_bus import FaultConfig
from sim.servo_emulator_pty import PtyServoEmulator, make_bus_emulator
from teleop.devices.dynamixel_bus import (
    BusTransactionError,
    DynamixelBus,
    Goal,
    ServoError,
    decode_load_p1,
    decode_speed_p1,
)
from teleop.errors import DeviceNotConnected

IDS = (1, 2, 3, 4)


def test_protocol1_load_and_speed_direction_bit_10() -> None:
    assert decode_load_p1(300) == -300  # 0..1023: CCW
    assert decode_load_p1(1024 + 300) == 300  # bit 10 set: CW
    assert decode_load_p1(0) == 0 and decode_load_p1(1024) == 0
    assert decode_speed_p1(200) == 200
    assert decode_speed_p1(0x400 | 200) == -200


@pytest.fixture(params=[1, 2], ids=["p1", "p2"])
def emu(request: pytest.FixtureRequest) -> Iterator[PtyServoEmulator]:
    e = PtyServoEmulator(make_bus_emulator(request.param, homes_counts=(10, -20, 30, -40),
                                           physics="simple"))
    e.start()
    yield e
    e.stop()


def make_bus(emu: PtyServoEmulator, **kw: float) -> DynamixelBus:
    opts = {"retries": 2, "timeout_s": 0.2} | kw
    bus = DynamixelBus(emu.path, 57142, float(emu.bus.protocol), IDS, **opts)  # type: ignore[arg-type]
    bus.open()
    return bus


def test_state_read_and_multi_turn_goals(emu: PtyServoEmulator) -> None:
    bus = make_bus(emu)
    try:
        assert [bus.ping(i) for i in IDS] == [29 if emu.bus.protocol == 1 else 30] * 4
        states = bus.read_states()
        assert [s.position_counts for s in states] == [10, -20, 30, -40]
        assert all(abs(s.voltage_v - 12.0) < 0.01 and s.temperature_c == 35 for s in states)
        for i in IDS:
            bus.write(i, "torque_enable", 1)
        bus.write_goals({1: Goal(-150, 0), 2: Goal(300, 0), 3: Goal(30, 0), 4: Goal(-40, 0)})
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline:
            states = bus.read_states()
            if abs(states[0].position_counts + 150) < 5 and abs(
                    states[1].position_counts - 300) < 5:
                break
            time.sleep(0.05)
        assert abs(states[0].position_counts + 150) < 5  # negative (multi-turn, signed)
        assert abs(states[1].position_counts - 300) < 5
        assert bus.read(1, "goal_position") == -150
    finally:
        bus.close()


def test_protocol1_bulk_read_matches_single_reads() -> None:
    e = PtyServoEmulator(make_bus_emulator(1, homes_counts=(10, -20, 30, -40), physics="simple",
                                           faults=FaultConfig(overload_ids=(3,))))
    e.start()
    try:
        single = make_bus(e)
        bulk = make_bus(e, bulk_read=True)
        a, b = single.read_states(), bulk.read_states()
        assert [s.position_counts for s in b] == [10, -20, 30, -40]
        assert [(s.position_counts, s.error) for s in a] == [(s.position_counts, s.error)
                                                            for s in b]
        assert b[2].hardware_faults == ("overload",)
        assert e.bus.counters.by_instruction.get(0x92) == 1
        single.close()
        bulk.close()
    finally:
        e.stop()


def test_servo_refusal_is_a_servo_error(emu: PtyServoEmulator) -> None:
    bus = make_bus(emu)
    try:
        name = "moving_speed" if emu.bus.protocol == 1 else "present_position"
        with pytest.raises(ServoError, match="refused"):
            bus.write(1, name, 2000)
    finally:
        bus.close()


def test_hardware_error_bits_are_decoded(emu: PtyServoEmulator) -> None:
    emu.bus.faults = FaultConfig(overload_ids=(2,), overheat_ids=(4,))
    bus = make_bus(emu)
    try:
        states = bus.read_states()
        assert states[1].hardware_faults == ("overload",)
        assert states[3].hardware_faults == ("overheat",)
        assert states[3].temperature_c == 85
        assert states[0].hardware_faults == ()
    finally:
        bus.close()


def test_dropped_and_corrupt_replies_are_retried_and_logged(
        emu: PtyServoEmulator, caplog: pytest.LogCaptureFixture) -> None:
    bus = make_bus(emu, retries=6, timeout_s=0.03)
    try:
        emu.bus.faults = FaultConfig(drop_rate=0.08, corrupt_rate=0.08, seed=4)
        with caplog.at_level(logging.WARNING, logger="teleop.devices.dynamixel"):
            for _ in range(10):
                assert len(bus.read_states()) == 4
        text = caplog.text
        assert "There is no status packet (attempt 1 of 7)" in text
        assert "Incorrect status packet" in text
        assert bus.failed_attempts > 0
        emu.bus.faults = FaultConfig(drop_rate=1.0)
        t0 = time.monotonic()
        with pytest.raises(BusTransactionError, match="failed after 7 attempts"):
            bus.read_states()
        assert time.monotonic() - t0 < 2.0
    finally:
        bus.close()


def test_missing_port_is_one_line_device_not_connected() -> None:
    bus = DynamixelBus("/dev/ttyNOPE9", 57142, 1.0, IDS)
    with pytest.raises(DeviceNotConnected) as info:
        bus.open()
    assert "/dev/ttyNOPE9" in str(info.value) and "\n" not in str(info.value)


def test_vanished_port_is_device_not_connected_without_hanging(emu: PtyServoEmulator) -> None:
    bus = make_bus(emu)
    assert len(bus.read_states()) == 4
    emu.vanish()
    t0 = time.monotonic()
    with pytest.raises(DeviceNotConnected, match="vanished"):
        for _ in range(3):
            bus.read_states()
    assert time.monotonic() - t0 < 2.0
    bus.close()  # closing a vanished port does not raise
