"""Emulated Dynamixel MX-28 servos: control table, instructions, status replies, faults.

:class:`EmulatedServo` holds one servo's control table (EEPROM + RAM, the real addresses from
:mod:`teleop.devices.dynamixel_tables`) and turns it into a :class:`ServoDrive` for the
physics and its measurements back into the present-value registers.  The instruction handling
for a bus of servos is :mod:`sim.servo_emulator_bus`, the physics
:mod:`sim.servo_emulator_physics`, and the pseudo-terminal I/O and the ``teleop
servo-emulator`` loop :mod:`sim.servo_emulator_pty`.
"""

from __future__ import annotations

from collections.abc import Sequence

from sim.servo_emulator_physics import ServoDrive, ServoSense
from teleop.devices import dynamixel_tables as T


def _to_unsigned(value: int, size: int) -> int:
    return value & ((1 << (8 * size)) - 1)


class EmulatedServo:
    """One MX-28: a control table and its mapping to physics."""

    def __init__(self, dxl_id: int, protocol: int, home_counts: int = 0, inversion: int = 1,
                 return_delay_us: int = 0) -> None:
        self.protocol = protocol
        self.inversion = inversion
        self.table = T.P1_TABLE if protocol == 1 else T.P2_TABLE
        size = T.P1_TABLE_SIZE if protocol == 1 else T.P2_TABLE_SIZE
        self.mem = bytearray(size)
        for reg in self.table.values():
            if reg.default is not None:
                self.poke(reg.name, reg.default)
        self.poke("id", dxl_id)
        self.poke("return_delay_time", max(0, min(254, return_delay_us // 2)))
        if protocol == 1:  # the ReFlex servos: multi-turn, resolution divider 4
            self.poke("cw_angle_limit", 4095)
            self.poke("ccw_angle_limit", 4095)
            self.poke("resolution_divider", T.P1_RESOLUTION_DIVIDER)
        else:
            self.poke("operating_mode", T.P2_OPERATING_MODE_MULTI_TURN)
        self.poke("present_position", home_counts)
        self.poke("goal_position", home_counts)
        self.pending: tuple[int, bytes] | None = None  # REG_WRITE buffer
        self.hw_error = 0  # P1 error bits / P2 hardware error status bits (reported)
        self.hw_condition = 0  # the injected cause; P2 latches it in hw_error until REBOOT
        self.reboots = 0

    # ---- raw table access
    def peek(self, name: str) -> int:
        """Read a register as an integer (signed when the register is)."""
        reg = self.table[name]
        value = int.from_bytes(self.mem[reg.address:reg.address + reg.size], "little",
                               signed=reg.signed)
        if self.protocol == 1 and name in ("goal_position", "present_position") \
                and not self.multi_turn:
            value &= 0xFFFF
        return value

    def poke(self, name: str, value: int) -> None:
        """Write a register (no checks; the servo's own updates)."""
        reg = self.table[name]
        self.mem[reg.address:reg.address + reg.size] = _to_unsigned(int(value), reg.size) \
            .to_bytes(reg.size, "little")

    @property
    def dxl_id(self) -> int:
        return self.mem[self.table["id"].address]

    @property
    def multi_turn(self) -> bool:
        if self.protocol == 1:
            return self.peek("cw_angle_limit") == 4095 and self.peek("ccw_angle_limit") == 4095
        return self.peek("operating_mode") == T.P2_OPERATING_MODE_MULTI_TURN

    @property
    def rad_per_count(self) -> float:
        if self.protocol == 1:
            return T.P1_RAD_PER_COUNT * self.peek("resolution_divider") / T.P1_RESOLUTION_DIVIDER
        return T.P2_RAD_PER_COUNT

    @property
    def return_delay_s(self) -> float:
        return 2e-6 * self.peek("return_delay_time")

    def read(self, address: int, length: int) -> tuple[bytes, bool]:
        """``length`` bytes from ``address``; False when the range is outside the table."""
        ok = address >= 0 and address + length <= len(self.mem)
        data = bytes(self.mem[address:address + length]) if ok else b""
        return data.ljust(length, b"\x00"), ok

    def write(self, address: int, data: bytes) -> int:
        """A WRITE from the bus; returns the instruction error (P1 bits / P2 number), 0 = ok."""
        end = address + len(data)
        if address < 0 or end > len(self.mem) or not data:
            return T.P1_ERR_RANGE if self.protocol == 1 else T.P2_ERR_DATA_LENGTH
        touched = [r for r in self.table.values()
                   if r.address < end and address < r.address + r.size]
        eeprom_end = T.P1_EEPROM_END if self.protocol == 1 else T.P2_EEPROM_END
        for reg in touched:
            if not reg.writable:
                return T.P1_ERR_RANGE if self.protocol == 1 else T.P2_ERR_ACCESS
            if self.protocol == 2 and reg.address < eeprom_end and self.peek("torque_enable"):
                return T.P2_ERR_ACCESS
        staged = bytearray(self.mem)
        staged[address:end] = data
        err = self._check(staged, [r for r in touched if r.address >= address
                                   and r.address + r.size <= end])
        if err:
            return err
        self.mem[:] = staged
        return 0

    def _check(self, mem: bytearray, regs: Sequence[T.Register]) -> int:
        """Range checks of the registers fully written."""
        p1 = self.protocol == 1
        for reg in regs:
            v = int.from_bytes(mem[reg.address:reg.address + reg.size], "little",
                               signed=reg.signed)
            bad = False
            if p1 and reg.name == "goal_position":
                cw = int.from_bytes(mem[6:8], "little")
                ccw = int.from_bytes(mem[8:10], "little")
                if cw == 4095 and ccw == 4095:
                    bad = not T.P1_MULTI_TURN_MIN <= v <= T.P1_MULTI_TURN_MAX
                elif not cw <= (v & 0xFFFF) <= ccw:
                    return T.P1_ERR_ANGLE
            elif p1 and reg.name in ("moving_speed", "torque_limit", "max_torque"):
                bad = v > 1023
            elif p1 and reg.name in ("cw_angle_limit", "ccw_angle_limit"):
                bad = v > 4095
            elif not p1 and reg.name == "goal_position" and mem[11] == 4:
                bad = not T.P2_POSITION_MIN <= v <= T.P2_POSITION_MAX
            elif not p1 and reg.name == "goal_pwm":
                bad = v > int.from_bytes(mem[36:38], "little")
            elif not p1 and reg.name == "profile_velocity":
                bad = v > int.from_bytes(mem[44:48], "little")
            elif reg.name == "torque_enable":
                bad = v > 1
            if bad:
                return T.P1_ERR_RANGE if p1 else T.P2_ERR_DATA_LIMIT
        return 0

    # ---- physics coupling
    def drive(self) -> ServoDrive:
        """The control table as a physics command."""
        if self.protocol == 1:
            goal = self.peek("goal_position") - self.peek("multi_turn_offset")
            speed = self.peek("moving_speed") * T.P1_RAD_S_PER_SPEED_UNIT
            limit = min(self.peek("torque_limit"), self.peek("max_torque")) / 1023.0
        else:
            goal = self.peek("goal_position") - self.peek("homing_offset")
            speed = self.peek("profile_velocity") * T.P2_RAD_S_PER_SPEED_UNIT
            limit = self.peek("goal_pwm") / T.P2_PWM_MAX
        return ServoDrive(bool(self.peek("torque_enable")), goal * self.rad_per_count, speed,
                          max(0.0, min(1.0, limit)))

    def sense(self, s: ServoSense) -> None:
        """Copy a physics measurement into the present-value registers."""
        counts = round(s.angle_rad / self.rad_per_count)
        # finger load is "pull" positive; as a Dynamixel load it reads CW for inversion +1
        cw_load = max(-1023, min(1023, round(s.load_pull_units * self.inversion)))
        if self.protocol == 1:
            counts += self.peek("multi_turn_offset")
            counts = max(T.P1_MULTI_TURN_MIN, min(T.P1_MULTI_TURN_MAX, counts))
            speed = min(1023, round(abs(s.velocity_rad_s) / T.P1_RAD_S_PER_SPEED_UNIT))
            self.poke("present_position", counts)
            self.poke("present_speed", speed | (0x400 if s.velocity_rad_s < 0 else 0))
            self.poke("present_load", 1024 + cw_load if cw_load > 0 else -cw_load)
            self.poke("present_voltage", 120)
        else:
            self.poke("present_position", counts + self.peek("homing_offset"))
            self.poke("present_velocity", round(s.velocity_rad_s / T.P2_RAD_S_PER_SPEED_UNIT))
            self.poke("present_load", -cw_load)
            self.poke("present_input_voltage", 120)
        hot = self.hw_error & (T.P1_ERR_OVERHEAT if self.protocol == 1 else T.P2_HW_OVERHEAT)
        self.poke("present_temperature", 85 if hot else 35)
        self.poke("moving", int(abs(s.velocity_rad_s) > 0.02))
        if self.protocol == 2:
            self.poke("hardware_error_status", self.hw_error)
        if self.hw_error & self.peek("shutdown"):
            self.poke("torque_enable", 0)  # alarm shutdown, like the real servo

    def set_condition(self, bits: int) -> None:
        """The hardware fault conditions now present: P1.0 reports exactly these; P2.0
        latches them in the hardware error status, which only :meth:`reboot` clears."""
        self.hw_condition = bits
        self.hw_error = bits if self.protocol == 1 else self.hw_error | bits

    def reboot(self) -> None:
        """REBOOT (P2.0): the error status restarts from the conditions still present, the
        RAM area (torque) from its defaults: torque off."""
        self.reboots += 1
        self.hw_error = self.hw_condition
        self.poke("torque_enable", 0)
        self.pending = None

    def status_error(self, instr_error: int = 0) -> int:
        """The error byte of a status packet."""
        if self.protocol == 1:
            return (self.hw_error | instr_error) & 0x7F
        return (T.P2_ERR_ALERT if self.hw_error else 0) | instr_error
