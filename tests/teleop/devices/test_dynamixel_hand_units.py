"""DynamixelHand's ReFlex conventions against a scripted bus (no serial port)."""

from __future__ import annotations

import math
from collections.abc import Mapping

import pytest

from teleop.config.hand import DynamixelConfig, HandConfig
from teleop.devices import dynamixel_tables as T
from teleop.devices.dynamixel_bus import BusTransactionError, Goal, ServoStatus
from teleop.devices.dynamixel_hand import DynamixelHand, build_dynamixel_hand
from teleop.errors import ConfigError, DeviceError
from teleop.messages import HandCommand, HandMode, Header

H = Header(1, 0.0, 0.0)


class FakeBus:
    """Servos whose present position follows the last goal; loads are set by the test."""

    protocol = 1
    rad_per_count = T.P1_RAD_PER_COUNT
    rad_s_per_speed_unit = T.P1_RAD_S_PER_SPEED_UNIT
    port_name = "/dev/fake"

    def __init__(self, ids: tuple[int, ...] = (1, 2, 3, 4)) -> None:
        self.ids = ids
        self.retries = 2
        self.positions = dict.fromkeys(ids, 0)
        self.loads_cw = dict.fromkeys(ids, 0)
        self.follow = True  # present position jumps to the goal
        self.goal_writes: list[dict[int, Goal]] = []
        self.writes: list[tuple[int, str, int]] = []
        self.fail = False
        self.is_open = False

    def open(self) -> None:
        self.is_open = True

    def close(self) -> None:
        self.is_open = False

    def ping(self, dxl_id: int) -> int:
        return T.P1_MODEL_NUMBER

    def read(self, dxl_id: int, name: str) -> int:
        return {"cw_angle_limit": 4095, "ccw_angle_limit": 4095,
                "resolution_divider": 4}.get(name, 0)

    def write(self, dxl_id: int, name: str, value: int) -> int:
        self.writes.append((dxl_id, name, value))
        return 0

    def write_goals(self, goals: Mapping[int, Goal]) -> None:
        if self.fail:
            raise BusTransactionError("/dev/fake: synchronised goal write failed")
        self.goal_writes.append(dict(goals))
        if self.follow:
            for i, g in goals.items():
                self.positions[i] = g.position_counts

    def read_states(self) -> tuple[ServoStatus, ...]:
        if self.fail:
            raise BusTransactionError("/dev/fake: state read of servo 1 failed after 3 "
                                      "attempts (There is no status packet)")
        return tuple(ServoStatus(i, self.positions[i], 0.0, self.loads_cw[i], 12.0, 35.0, 0)
                     for i in self.ids)


def cmd(fingers: tuple[float, float, float], preshape: float = 0.0,
        mode: HandMode = HandMode.POSITION,
        force: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> HandCommand:
    return HandCommand(H, fingers, preshape, mode, force)


def make(**kw: object) -> tuple[DynamixelHand, FakeBus, list[float]]:
    bus = FakeBus()
    now = [0.0]
    hand = DynamixelHand(bus, DynamixelConfig(**kw), clock=lambda: now[0],  # type: ignore[arg-type]
                         sleep=lambda s: now.__setitem__(0, now[0] + s))
    hand.start()
    return hand, bus, now


def joints_of(hand: DynamixelHand, goals: dict) -> list[float]:
    return [hand.joint_from_counts(k, goals[i].position_counts)
            for k, i in enumerate(hand.cfg.ids)]


def test_joint_angle_convention_ratio_inversion_and_zero() -> None:
    hand, bus, _ = make(zeros_rad=(0.1, -0.2, 0.0, 0.3))
    scale = T.P1_RAD_PER_COUNT
    assert scale == pytest.approx(8 * math.pi / 4095)
    # joint = inversion * (raw * scale / ratio - zero)
    assert hand.joint_from_counts(0, 1000) == pytest.approx(1000 * scale / 1.42 - 0.1)
    assert hand.joint_from_counts(1, 1000) == pytest.approx(-(1000 * scale / 1.42 + 0.2))
    assert hand.joint_from_counts(3, -500) == pytest.approx(-(-500 * scale / 1.5 - 0.3))
    for k in range(4):
        c = hand.counts_from_joint(k, 0.7)
        assert abs(hand.joint_from_counts(k, c) - 0.7) < scale


def test_set_points_are_clamped_to_travel_before_reaching_a_motor() -> None:
    hand, bus, _ = make()
    hand.apply(cmd((10.0, -3.0, 2.0), preshape=5.0))
    j = joints_of(hand, bus.goal_writes[-1])
    assert j[0] == pytest.approx(3.6, abs=0.005)
    assert j[1] == pytest.approx(0.0, abs=0.005)
    assert j[2] == pytest.approx(2.0, abs=0.005)
    assert j[3] == pytest.approx(1.75, abs=0.005)
    # finger 2 (inversion -1) closes with decreasing counts
    hand.apply(cmd((0.0, 1.0, 0.0)))
    assert bus.goal_writes[-1][2].position_counts < 0


def test_overload_backs_the_target_off_to_present_minus_0p05() -> None:
    hand, bus, _ = make(load_filter=1.0)
    hand.apply(cmd((1.0, 1.0, 1.0)))
    hand.read(0.0)
    bus.follow = False
    bus.loads_cw[1] = 500  # finger 1, inversion +1: pulling load 500 > 350
    hand.apply(cmd((2.0, 1.0, 1.0)))  # would move further in
    reading = hand.read(0.025)
    assert reading.fingers[0].load_units == 500
    assert hand.target[0] == pytest.approx(1.0 - 0.05, abs=0.005)
    assert joints_of(hand, bus.goal_writes[-1])[0] == pytest.approx(0.95, abs=0.005)
    assert any("overloaded" in f for f in reading.faults)
    # finger 2's load reads with the opposite sign convention (inversion -1)
    bus.loads_cw[2] = -400
    assert hand.read(0.05).fingers[1].load_units == 400


def test_command_pacing_delays_commands_by_0p09_s() -> None:
    hand, bus, now = make(command_pacing=True)
    n = len(bus.goal_writes)
    hand.apply(cmd((1.0, 1.0, 1.0)))
    now[0] = 0.08
    hand.read(0.08)
    assert len(bus.goal_writes) == n
    now[0] = 0.0901
    hand.read(0.09)
    assert len(bus.goal_writes) == n + 1
    assert joints_of(hand, bus.goal_writes[-1])[0] == pytest.approx(1.0, abs=0.005)


def test_force_mode_integrates_load_error() -> None:
    hand, bus, _ = make(load_filter=1.0)
    bus.follow = False
    hand.apply(cmd((0.5, 0.5, 0.5)))
    bus.loads_cw[1] = 100
    hand.read(0.0)
    before = hand.target[0]
    hand.apply(cmd((0.0, 0.0, 0.0), mode=HandMode.FORCE, force=(300.0, 100.0, 100.0)))
    assert hand.target[0] - before == pytest.approx(4e-5 * 200, rel=1e-6)


def test_velocity_mode_is_a_position_move_at_the_configured_speed() -> None:
    hand, bus, _ = make()
    hand.apply(cmd((0.5, 5.0, -1.0), mode=HandMode.VELOCITY))
    g = bus.goal_writes[-1]
    assert joints_of(hand, g)[0] == pytest.approx(0.5, abs=0.005)
    assert joints_of(hand, g)[1] == pytest.approx(3.6, abs=0.005)  # clamped to travel
    assert joints_of(hand, g)[2] == pytest.approx(0.0, abs=0.005)
    assert g[1].speed_units == round(hand.cfg.speed_rad_s * 1.42 / T.P1_RAD_S_PER_SPEED_UNIT)


def test_consecutive_bus_failures_latch_the_safe_state() -> None:
    hand, bus, _ = make(max_failures=3)
    hand.apply(cmd((1.0, 1.0, 1.0)))
    hand.read(0.0)
    bus.fail = True
    for k in range(2):
        r = hand.read(0.025 * k)
        assert not hand.safe_reason and any("no status packet" in f for f in r.faults)
    r = hand.read(0.1)
    assert "3 consecutive bus failures" in hand.safe_reason
    assert any("safe state" in f for f in r.faults)
    bus.fail = False
    n = len(bus.goal_writes)
    hand.apply(cmd((2.0, 2.0, 2.0)))  # ignored while latched
    assert len(bus.goal_writes) == n
    assert any("safe state" in f for f in hand.read(0.2).faults)  # reported every read


def test_load_based_calibration_backs_off_50_counts() -> None:
    hand, bus, _ = make(calibrate=False, calibration_load_units=40.0)
    rise_at = {1: 300, 2: -120, 3: 60}  # tendon taut at these raw counts (closing direction)

    def read_states():  # type: ignore[no-untyped-def]
        for i, c in rise_at.items():
            inv = hand.inv[i - 1]
            bus.loads_cw[i] = inv * (80 if inv * bus.positions[i] >= inv * c else 5)
        return FakeBus.read_states(bus)

    bus.read_states = read_states  # type: ignore[method-assign]
    zeros = hand.calibrate()
    for k, i in enumerate((1, 2, 3)):
        zero_counts = zeros[k] * 1.42 / T.P1_RAD_PER_COUNT
        first_hit = rise_at[i] + (6 * hand.inv[k] if hand.inv[k] > 0 else -6)  # 2nd step above
        assert abs(zero_counts - (first_hit - 50 * hand.inv[k])) <= 7
    assert [hand.joint[k] for k in range(3)] == pytest.approx([0, 0, 0], abs=0.01)


def test_bad_config_is_one_line_config_error() -> None:
    with pytest.raises(ConfigError, match="hand.dynamixel.ids"):
        build_dynamixel_hand(HandConfig(dynamixel=DynamixelConfig(ids=(1, 2, 3))))
    with pytest.raises(ConfigError, match="inversion"):
        DynamixelHand(FakeBus(), DynamixelConfig(inversion=(1, 2, 1, -1)))  # type: ignore[arg-type]


def test_wrong_servo_setup_is_a_clear_device_error() -> None:
    bus = FakeBus()
    bus.read = lambda i, name: 0  # type: ignore[method-assign]  # joint mode, divider 0
    with pytest.raises(DeviceError, match="multi-turn"):
        DynamixelHand(bus, DynamixelConfig()).start()  # type: ignore[arg-type]
