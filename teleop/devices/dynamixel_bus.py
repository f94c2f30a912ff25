"""A thin wrapper over dynamixel-sdk for a bus of MX-28s (Protocol 1.0 or 2.0).

What it adds to the SDK: a one-line :class:`~teleop.errors.DeviceNotConnected` for a missing or
vanished port (never a hang or traceback), retries of failed transactions with a clear log
message for each, a reply timeout from config, decoded state reads, and the protocol-specific
registers behind one API.  dynamixel-sdk is imported when the bus is opened.

Per cycle the bus does one synchronised goal write (GroupSyncWrite of goal position + moving
speed) and a state read: Protocol 2.0 uses GroupSyncRead; Protocol 1.0 uses one READ per servo
of the block present position .. present temperature (each reply carries the servo's error
byte), or, with ``bulk_read=True``, one BULK_READ sent through the packet handler directly,
because GroupBulkRead is broken for 1.0 in dynamixel-sdk 4.1.

Example::

    bus = DynamixelBus("/dev/ttyUSB0", 57142, 1.0, (1, 2, 3, 4))
    bus.open()
    bus.write_goals({1: Goal(1200, 0), 2: Goal(-800, 0)})
    states = bus.read_states()
"""

from __future__ import annotations

import logging
import os
import select
import termios
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from teleop.devices import dynamixel_tables as T
from teleop.errors import DeviceError, DeviceNotConnected

log = logging.getLogger("teleop.devices.dynamixel")


class BusTransactionError(DeviceError):
    """A bus transaction failed on every attempt (timeout, corrupt reply)."""


class ServoError(DeviceError):
    """A servo refused an instruction (range, angle limit, instruction or access error)."""


@dataclass(frozen=True, slots=True)
class Goal:
    """One servo's goal: position (raw counts, signed) and moving speed (raw units, 0 = max)."""

    position_counts: int
    speed_units: int = 0


@dataclass(frozen=True, slots=True)
class ServoStatus:
    """One servo's decoded state."""

    dxl_id: int
    position_counts: int  # signed, multi-turn
    velocity_rad_s: float  # shaft, CCW positive
    load_cw_units: int  # signed load, 0.1 % of max torque; positive = CW (1024..2047 in P1.0)
    voltage_v: float
    temperature_c: float
    error: int  # P1.0: status error byte; P2.0: hardware error status
    protocol: int = 1

    @property
    def hardware_faults(self) -> tuple[str, ...]:
        """Names of the hardware error bits set (overload, overheat, input voltage...)."""
        return hardware_fault_names(self.error, self.protocol)


def hardware_fault_names(error: int, protocol: int) -> tuple[str, ...]:
    """Names of the set hardware bits of a P1.0 error byte / P2.0 hardware error status."""
    names = T.P1_ERROR_NAMES if protocol == 1 else T.P2_HW_ERROR_NAMES
    hw = (T.P1_ERR_VOLTAGE | T.P1_ERR_OVERHEAT | T.P1_ERR_OVERLOAD) if protocol == 1 else 0xFF
    return tuple(name for bit, name in names.items() if error & bit & hw)


def _signed(value: int, size: int) -> int:
    bits = 8 * size
    value &= (1 << bits) - 1
    return value - (1 << bits) if value >> (bits - 1) else value


def _le(value: int, size: int) -> list[int]:
    value &= (1 << (8 * size)) - 1
    return [(value >> (8 * k)) & 0xFF for k in range(size)]


def decode_load_p1(raw: int) -> int:
    """Protocol 1.0 present load -> signed, CW positive (0..1023 CCW, 1024..2047 CW)."""
    return raw - 1024 if raw >= 1024 else -raw


def decode_speed_p1(raw: int) -> int:
    """Protocol 1.0 present speed -> signed units, CCW positive (bit 10 set = CW)."""
    return -(raw & 0x3FF) if raw & 0x400 else raw & 0x3FF


class DynamixelBus:
    """Servos on one serial port through dynamixel-sdk."""

    def __init__(self, port: str, baud_rate: int, protocol: float, ids: Sequence[int], *,
                 retries: int = 2, timeout_s: float = 0.02, bulk_read: bool = False) -> None:
        if protocol not in (1.0, 2.0):
            raise ValueError(f"protocol must be 1.0 or 2.0, got {protocol}")
        self.port_name = port
        self.baud_rate = baud_rate
        self.protocol = int(protocol)
        self.ids = tuple(ids)
        self.retries = retries
        self.timeout_s = timeout_s
        self.bulk_read = bulk_read
        self.rad_per_count = T.P1_RAD_PER_COUNT if self.protocol == 1 else T.P2_RAD_PER_COUNT
        self.rad_s_per_speed_unit = (T.P1_RAD_S_PER_SPEED_UNIT if self.protocol == 1
                                     else T.P2_RAD_S_PER_SPEED_UNIT)
        self.table = T.P1_TABLE if self.protocol == 1 else T.P2_TABLE
        self.transactions = 0
        self.failed_attempts = 0
        self._sdk: Any = None
        self._port: Any = None
        self._ph: Any = None
        self._sync_state: Any = None
        self._sync_error: Any = None

    # ---- connection
    def open(self) -> None:
        """Open the port; DeviceNotConnected (one line) when it is missing or unusable."""
        try:
            import dynamixel_sdk as sdk
        except ImportError:
            raise DeviceError("dynamixel-sdk is not installed (pip install dynamixel-sdk)") \
                from None
        if not os.path.exists(self.port_name):
            raise DeviceNotConnected(f"{self.port_name}: serial port not found "
                                     "(is the hand's USB adapter plugged in?)")
        self._sdk = sdk
        self._port = _timed_port(sdk, self.port_name, self.timeout_s)
        self._port.baudrate = self.baud_rate  # setBaudRate rejects 57142: set, then setupPort
        try:
            self._port.setupPort(0)
        except (OSError, ValueError) as exc:  # serial.SerialException is an OSError
            self._port = None
            raise DeviceNotConnected(f"{self.port_name}: cannot open serial port "
                                     f"({_short(exc)})") from None
        self._ph = sdk.PacketHandler(float(self.protocol))
        if self.protocol == 2:
            self._sync_state = sdk.GroupSyncRead(self._port, self._ph, T.P2_STATE_START,
                                                 T.P2_STATE_LEN)
            self._sync_error = sdk.GroupSyncRead(self._port, self._ph, 70, 1)
            for i in self.ids:
                self._sync_state.addParam(i)
                self._sync_error.addParam(i)

    def close(self) -> None:
        """Close the port (never raises)."""
        if self._port is not None:
            try:
                if self._port.is_open:
                    self._port.closePort()
            except Exception:  # noqa: BLE001 - closing a vanished port must not raise
                pass
        self._port = None

    @property
    def is_open(self) -> bool:
        return self._port is not None

    # ---- transactions
    def _call(self, what: str, fn: Callable[[], tuple[int, int, Any]],
              retries: int | None = None) -> tuple[Any, int]:
        """Run ``fn`` (returns result, error, value) with retries; returns (value, error)."""
        if self._port is None:
            raise DeviceNotConnected(f"{self.port_name}: serial port is not open")
        attempts = 1 + (self.retries if retries is None else retries)
        reason = ""
        for attempt in range(1, attempts + 1):
            self.transactions += 1
            try:
                result, error, value = fn()
            except (OSError, ValueError, termios.error) as exc:  # SerialException is OSError
                self._port.is_using = False
                raise DeviceNotConnected(f"{self.port_name}: serial port vanished during "
                                         f"{what} ({_short(exc)})") from None
            checksum_bit = T.P1_ERR_CHECKSUM if self.protocol == 1 else None
            if result == self._sdk.COMM_SUCCESS and not (
                    checksum_bit is not None and error & checksum_bit) and not (
                    self.protocol == 2 and error & 0x7F == T.P2_ERR_CRC):
                return value, error
            self.failed_attempts += 1
            reason = (self._ph.getTxRxResult(result) if result != self._sdk.COMM_SUCCESS
                      else "servo reports a checksum error in our packet")
            reason = reason.replace("[TxRxResult] ", "").rstrip("!")
            log.warning("dynamixel %s: %s failed: %s (attempt %d of %d)", self.port_name,
                        what, reason, attempt, attempts)
        raise BusTransactionError(f"{self.port_name}: {what} failed after {attempts} "
                                  f"attempts ({reason})")

    def _check_servo(self, what: str, error: int) -> None:
        if self.protocol == 1:
            bad = error & (T.P1_ERR_RANGE | T.P1_ERR_ANGLE | T.P1_ERR_INSTRUCTION)
        else:
            bad = error & 0x7F
        if bad:
            text = (self._ph.getRxPacketError(bad).replace("[RxPacketError] ", "")
                    .rstrip("!"))
            raise ServoError(f"{self.port_name}: {what} refused: {text}")

    def ping(self, dxl_id: int) -> int:
        """Model number of servo ``dxl_id``."""
        def fn() -> tuple[int, int, Any]:
            model, result, error = self._ph.ping(self._port, dxl_id)
            return result, error, model
        model, _ = self._call(f"ping of servo {dxl_id}", fn)
        return int(model)

    def read(self, dxl_id: int, name: str) -> int:
        """Register ``name`` of servo ``dxl_id`` (signed when the register is)."""
        reg = self.table[name]

        def fn() -> tuple[int, int, Any]:
            data, result, error = self._ph.readTxRx(self._port, dxl_id, reg.address, reg.size)
            return result, error, data
        data, error = self._call(f"read of {name} from servo {dxl_id}", fn)
        self._check_servo(f"read of {name} from servo {dxl_id}", error)
        value = int.from_bytes(bytes(data[:reg.size]), "little")
        return _signed(value, reg.size) if reg.signed else value

    def write(self, dxl_id: int, name: str, value: int) -> int:
        """Write register ``name`` of servo ``dxl_id``; returns the status error byte."""
        reg = self.table[name]

        def fn() -> tuple[int, int, Any]:
            result, error = self._ph.writeTxRx(self._port, dxl_id, reg.address, reg.size,
                                               _le(value, reg.size))
            return result, error, None
        what = f"write of {name}={value} to servo {dxl_id}"
        _, error = self._call(what, fn)
        self._check_servo(what, error)
        return int(error)

    def reboot(self, dxl_id: int) -> None:
        """REBOOT servo ``dxl_id`` (protocol 2.0): clears its latched hardware error status
        when the cause has gone; the servo comes back with torque off."""
        def fn() -> tuple[int, int, Any]:
            result, error = self._ph.reboot(self._port, dxl_id)
            return result, error, None
        what = f"reboot of servo {dxl_id}"
        _, error = self._call(what, fn)
        self._check_servo(what, error)

    def write_goals(self, goals: Mapping[int, Goal]) -> None:
        """One synchronised write of goal position and moving speed to every servo in ``goals``."""
        sdk = self._sdk
        if self.protocol == 1:
            start, length = T.P1_GOAL_START, T.P1_GOAL_LEN
            blocks = {i: _le(g.position_counts, 2) + _le(g.speed_units, 2)
                      for i, g in goals.items()}
        else:
            start, length = T.P2_GOAL_START, T.P2_GOAL_LEN
            blocks = {i: _le(g.speed_units, 4) + _le(g.position_counts, 4)
                      for i, g in goals.items()}
        group = sdk.GroupSyncWrite(self._port, self._ph, start, length)
        for i, block in blocks.items():
            group.addParam(i, block)

        def fn() -> tuple[int, int, Any]:
            return group.txPacket(), 0, None
        self._call("synchronised goal write", fn)

    def read_states(self) -> tuple[ServoStatus, ...]:
        """Present position, speed, load, voltage, temperature and error of every servo."""
        if self.protocol == 1 and self.bulk_read:
            return self._read_states_p1_bulk()
        if self.protocol == 1:
            return tuple(self._read_state_p1(i) for i in self.ids)
        return self._read_states_p2()

    def _decode_p1(self, dxl_id: int, d: Sequence[int], error: int) -> ServoStatus:
        speed = decode_speed_p1(d[2] | (d[3] << 8))
        return ServoStatus(dxl_id, _signed(d[0] | (d[1] << 8), 2),
                           speed * self.rad_s_per_speed_unit, decode_load_p1(d[4] | (d[5] << 8)),
                           d[6] * T.VOLTS_PER_UNIT, float(d[7]), error)

    def _read_states_p1_bulk(self) -> tuple[ServoStatus, ...]:
        """One Protocol 1.0 BULK_READ (0x92) for every servo.

        dynamixel-sdk 4.1's GroupBulkRead calls the 1.0 handler's ``bulkReadTx`` with one
        argument too many (TypeError), so the handler's own ``bulkReadTx``/``readRx`` are used.
        """
        param = [v for i in self.ids for v in (T.P1_STATE_LEN, i, T.P1_STATE_START)]

        def fn() -> tuple[int, int, Any]:
            result = self._ph.bulkReadTx(self._port, param, len(param))
            if result != self._sdk.COMM_SUCCESS:
                self._port.is_using = False
                return result, 0, None
            out = []
            for i in self.ids:
                data, result, error = self._ph.readRx(self._port, i, T.P1_STATE_LEN)
                if result != self._sdk.COMM_SUCCESS:
                    return result, 0, None
                out.append(self._decode_p1(i, data, error))
            return result, 0, tuple(out)
        states, _ = self._call("bulk state read", fn)
        return states  # type: ignore[no-any-return]

    def _read_state_p1(self, dxl_id: int) -> ServoStatus:
        def fn() -> tuple[int, int, Any]:
            data, result, error = self._ph.readTxRx(self._port, dxl_id, T.P1_STATE_START,
                                                    T.P1_STATE_LEN)
            return result, error, data
        d, error = self._call(f"state read of servo {dxl_id}", fn)
        return self._decode_p1(dxl_id, d, error)

    def _read_states_p2(self) -> tuple[ServoStatus, ...]:
        state, errs = self._sync_state, self._sync_error

        def fn_state() -> tuple[int, int, Any]:
            return state.txRxPacket(), 0, None

        def fn_error() -> tuple[int, int, Any]:
            return errs.txRxPacket(), 0, None
        self._call("synchronised state read", fn_state)
        self._call("hardware error read", fn_error)
        out = []
        for i in self.ids:
            def get(addr: int, size: int, dxl_id: int = i) -> int:
                return _signed(state.getData(dxl_id, addr, size), size)
            out.append(ServoStatus(
                i, get(132, 4), get(128, 4) * self.rad_s_per_speed_unit, -get(126, 2),
                (state.getData(i, 144, 2)) * T.VOLTS_PER_UNIT, float(state.getData(i, 146, 1)),
                errs.getData(i, 70, 1), 2))
        return tuple(out)


def _short(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return text[:120]


def _timed_port(sdk: Any, name: str, timeout_s: float) -> Any:
    """A PortHandler whose reply timeout is ``timeout_s`` plus the bytes' transmission time
    (the stock one waits 2 x 16 ms for a USB latency timer) and whose reads do not spin."""

    class _TimedPort(sdk.PortHandler):  # type: ignore[misc, name-defined]
        def setPacketTimeout(self, packet_length: int) -> None:  # noqa: N802 - SDK name
            self.packet_start_time = self.getCurrentTime()
            self.packet_timeout = self.tx_time_per_byte * packet_length + 1000.0 * timeout_s

        def readPort(self, length: int) -> bytes:  # noqa: N802 - SDK name
            # The SDK polls with a zero timeout; wait up to 0.5 ms for bytes instead of
            # spinning, which leaves the CPU to the servo side (an emulator on this machine).
            data = self.ser.read(length)
            if not data and length > 0:
                select.select([self.ser.fileno()], [], [], 0.0005)
                data = self.ser.read(length)
            return data  # type: ignore[no-any-return]

    return _TimedPort(name)
