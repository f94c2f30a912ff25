"""Dynamixel MX-28 control tables, units and protocol constants (data only, no logic).

Sources: ROBOTIS e-manual for the MX-28 (Protocol 1.0 firmware, model number 29, and
Protocol 2.0 firmware, model number 30) and the ReFlex driver conventions summarised in
``shared/reference/reflex-hardware.md``.  The servo emulator (``sim/servo_emulator.py``) and
the bus wrapper (:mod:`teleop.devices.dynamixel_bus`) both read their addresses from here so
the two can never disagree.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class Register:
    """One control-table entry."""

    name: str
    address: int
    size: int  # bytes, little-endian
    writable: bool
    default: int | None = None  # value after power-up; None = computed at run time
    signed: bool = False


def _table(*regs: Register) -> dict[str, Register]:
    return {r.name: r for r in regs}


R, W = False, True

#: MX-28, Protocol 1.0 (model 29).  EEPROM is addresses 0..23, RAM from 24.
P1_TABLE: dict[str, Register] = _table(
    Register("model_number", 0, 2, R, 29),
    Register("firmware_version", 2, 1, R, 36),
    Register("id", 3, 1, W, 1),
    Register("baud_rate", 4, 1, W, 34),  # bps = 2e6 / (value + 1); 34 -> 57142
    Register("return_delay_time", 5, 1, W, 250),  # 2 us per unit
    Register("cw_angle_limit", 6, 2, W, 0),
    Register("ccw_angle_limit", 8, 2, W, 4095),  # both 4095 = multi-turn mode
    Register("temperature_limit", 11, 1, W, 80),
    Register("min_voltage_limit", 12, 1, W, 60),
    Register("max_voltage_limit", 13, 1, W, 160),
    Register("max_torque", 14, 2, W, 1023),
    Register("status_return_level", 16, 1, W, 2),
    Register("alarm_led", 17, 1, W, 36),
    Register("shutdown", 18, 1, W, 36),  # error bits that switch the torque off
    Register("multi_turn_offset", 20, 2, W, 0, signed=True),
    Register("resolution_divider", 22, 1, W, 1),
    Register("torque_enable", 24, 1, W, 0),
    Register("led", 25, 1, W, 0),
    Register("d_gain", 26, 1, W, 0),
    Register("i_gain", 27, 1, W, 0),
    Register("p_gain", 28, 1, W, 32),
    Register("goal_position", 30, 2, W, None, signed=True),  # signed in multi-turn mode
    Register("moving_speed", 32, 2, W, 0),  # 0.114 rpm per unit, 0 = max
    Register("torque_limit", 34, 2, W, 1023),  # 0.1 % of max torque
    Register("present_position", 36, 2, R, None, signed=True),
    Register("present_speed", 38, 2, R, 0),  # bit 10 = direction (set = CW)
    Register("present_load", 40, 2, R, 0),  # 0..1023 CCW, 1024..2047 CW
    Register("present_voltage", 42, 1, R, 120),  # 0.1 V
    Register("present_temperature", 43, 1, R, 35),  # deg C
    Register("registered", 44, 1, R, 0),
    Register("moving", 46, 1, R, 0),
    Register("lock", 47, 1, W, 0),
    Register("punch", 48, 2, W, 0),
    Register("goal_acceleration", 73, 1, W, 0),
)
P1_EEPROM_END = 24  # first RAM address
P1_TABLE_SIZE = 74
P1_MODEL_NUMBER = 29

#: MX-28, Protocol 2.0 (model 30).  EEPROM is addresses 0..63, RAM from 64.
P2_TABLE: dict[str, Register] = _table(
    Register("model_number", 0, 2, R, 30),
    Register("model_information", 2, 4, R, 0),
    Register("firmware_version", 6, 1, R, 41),
    Register("id", 7, 1, W, 1),
    Register("baud_rate", 8, 1, W, 1),  # 1 = 57600
    Register("return_delay_time", 9, 1, W, 250),
    Register("drive_mode", 10, 1, W, 0),
    Register("operating_mode", 11, 1, W, 3),  # 1 velocity, 3 position, 4 multi-turn, 16 PWM
    Register("secondary_id", 12, 1, W, 255),
    Register("protocol_type", 13, 1, W, 2),
    Register("homing_offset", 20, 4, W, 0, signed=True),
    Register("moving_threshold", 24, 4, W, 10),
    Register("temperature_limit", 31, 1, W, 80),
    Register("max_voltage_limit", 32, 2, W, 160),
    Register("min_voltage_limit", 34, 2, W, 95),
    Register("pwm_limit", 36, 2, W, 885),
    Register("velocity_limit", 44, 4, W, 230),
    Register("max_position_limit", 48, 4, W, 4095),
    Register("min_position_limit", 52, 4, W, 0),
    Register("shutdown", 63, 1, W, 52),
    Register("torque_enable", 64, 1, W, 0),
    Register("led", 65, 1, W, 0),
    Register("status_return_level", 68, 1, W, 2),
    Register("registered_instruction", 69, 1, R, 0),
    Register("hardware_error_status", 70, 1, R, 0),
    Register("velocity_i_gain", 76, 2, W, 1920),
    Register("velocity_p_gain", 78, 2, W, 100),
    Register("position_d_gain", 80, 2, W, 0),
    Register("position_i_gain", 82, 2, W, 0),
    Register("position_p_gain", 84, 2, W, 850),
    Register("goal_pwm", 100, 2, W, 885),  # used as the torque limit (885 = 100 %)
    Register("goal_velocity", 104, 4, W, 0, signed=True),
    Register("profile_acceleration", 108, 4, W, 0),
    Register("profile_velocity", 112, 4, W, 0),  # 0.229 rpm per unit, 0 = max
    Register("goal_position", 116, 4, W, None, signed=True),
    Register("realtime_tick", 120, 2, R, 0),
    Register("moving", 122, 1, R, 0),
    Register("moving_status", 123, 1, R, 0),
    Register("present_pwm", 124, 2, R, 0, signed=True),
    Register("present_load", 126, 2, R, 0, signed=True),  # 0.1 %, positive = CCW
    Register("present_velocity", 128, 4, R, 0, signed=True),
    Register("present_position", 132, 4, R, None, signed=True),
    Register("velocity_trajectory", 136, 4, R, 0, signed=True),
    Register("position_trajectory", 140, 4, R, 0, signed=True),
    Register("present_input_voltage", 144, 2, R, 120),
    Register("present_temperature", 146, 1, R, 35),
)
P2_EEPROM_END = 64
P2_TABLE_SIZE = 147
P2_MODEL_NUMBER = 30

# ---- Protocol 1.0 status error bits
P1_ERR_VOLTAGE = 0x01
P1_ERR_ANGLE = 0x02
P1_ERR_OVERHEAT = 0x04
P1_ERR_RANGE = 0x08
P1_ERR_CHECKSUM = 0x10
P1_ERR_OVERLOAD = 0x20
P1_ERR_INSTRUCTION = 0x40
P1_ERROR_NAMES: dict[int, str] = {
    P1_ERR_VOLTAGE: "input voltage", P1_ERR_ANGLE: "angle limit", P1_ERR_OVERHEAT: "overheat",
    P1_ERR_RANGE: "range", P1_ERR_CHECKSUM: "checksum", P1_ERR_OVERLOAD: "overload",
    P1_ERR_INSTRUCTION: "instruction",
}

# ---- Protocol 2.0 status error field and hardware error status bits
P2_ERR_ALERT = 0x80
P2_ERR_RESULT_FAIL = 1
P2_ERR_INSTRUCTION = 2
P2_ERR_CRC = 3
P2_ERR_DATA_RANGE = 4
P2_ERR_DATA_LENGTH = 5
P2_ERR_DATA_LIMIT = 6
P2_ERR_ACCESS = 7
P2_HW_VOLTAGE = 0x01
P2_HW_OVERHEAT = 0x04
P2_HW_ENCODER = 0x08
P2_HW_SHOCK = 0x10
P2_HW_OVERLOAD = 0x20
P2_HW_ERROR_NAMES: dict[int, str] = {
    P2_HW_VOLTAGE: "input voltage", P2_HW_OVERHEAT: "overheat", P2_HW_ENCODER: "motor encoder",
    P2_HW_SHOCK: "electrical shock", P2_HW_OVERLOAD: "overload",
}

# ---- Instructions
INST_PING = 0x01
INST_READ = 0x02
INST_WRITE = 0x03
INST_REG_WRITE = 0x04
INST_ACTION = 0x05
INST_FACTORY_RESET = 0x06
INST_REBOOT = 0x08
INST_STATUS = 0x55
INST_SYNC_READ = 0x82
INST_SYNC_WRITE = 0x83
INST_BULK_READ = 0x92
BROADCAST_ID = 0xFE

# ---- Units
#: ReFlex position scale: multi-turn with resolution divider 4 (driver constant 8*pi/4095).
P1_RAD_PER_COUNT = 8.0 * math.pi / 4095.0
P1_RESOLUTION_DIVIDER = 4
P1_MULTI_TURN_MIN = -28672
P1_MULTI_TURN_MAX = 28672
#: Protocol 2.0 extended-position mode: 4096 counts per revolution, int32 range.
P2_RAD_PER_COUNT = 2.0 * math.pi / 4096.0
P2_OPERATING_MODE_MULTI_TURN = 4
P2_POSITION_MIN = -1_048_575
P2_POSITION_MAX = 1_048_575
#: Moving speed / present speed units (Protocol 1.0): 0.114 rpm.
P1_RAD_S_PER_SPEED_UNIT = 0.114 * 2.0 * math.pi / 60.0  # 0.01194 rad/s
#: Profile velocity / present velocity units (Protocol 2.0): 0.229 rpm.
P2_RAD_S_PER_SPEED_UNIT = 0.229 * 2.0 * math.pi / 60.0
P1_SPEED_MAX_UNITS = 1023
P1_TORQUE_LIMIT_MAX = 1023
P2_PWM_MAX = 885
P2_VELOCITY_LIMIT = 230  # default velocity limit (units of 0.229 rpm); profile velocity cap
LOAD_UNITS_FULL = 1023  # 100 % of max torque, 0.1 % per unit
VOLTS_PER_UNIT = 0.1
#: Baud-rate register -> bit/s (Protocol 1.0: 2e6/(v+1)); Protocol 2.0 uses a lookup.
P2_BAUD_RATES: dict[int, int] = {0: 9600, 1: 57600, 2: 115200, 3: 1_000_000, 4: 2_000_000}
#: MX-28 stall torque at 12 V and no-load speed (for the emulator's fallback model).
MX28_STALL_TORQUE_NM = 2.5
MX28_NO_LOAD_SPEED_RAD_S = 55.0 * 2.0 * math.pi / 60.0

#: The state block read every cycle.  Protocol 1.0: present position .. present temperature.
P1_STATE_START = 36
P1_STATE_LEN = 8
#: Protocol 2.0: present load .. present temperature.
P2_STATE_START = 126
P2_STATE_LEN = 21
#: Goal block written every cycle.  Protocol 1.0: goal position (2) + moving speed (2).
P1_GOAL_START = 30
P1_GOAL_LEN = 4
#: Protocol 2.0: profile velocity (4) + goal position (4).
P2_GOAL_START = 112
P2_GOAL_LEN = 8
