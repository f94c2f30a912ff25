"""A bus of emulated MX-28s: instruction handling, status replies and fault injection.

:class:`ServoBusEmulator` takes parsed instruction packets (:mod:`sim.dynamixel_packets`)
and returns the status packets the servos would send, in order, each with the delay before it
(the servo's return delay time plus any injected latency).  Rules followed (ROBOTIS manual):

* Broadcast ID 0xFE: no reply, except Protocol 2.0 PING, SYNC_READ and Protocol 1.0
  BULK_READ, where every addressed servo answers in turn.
* Status return level: 0 = PING only, 1 = PING and READ (incl. SYNC/BULK READ), 2 = all.
* A bad checksum/CRC is answered with the checksum error bit (1.0) / CRC error (2.0).
* Protocol 1.0 error byte: hardware bits (voltage, overheat, overload) OR the instruction's
  own error (range, angle limit, instruction, checksum).  Protocol 2.0: alert bit 0x80 when the
  hardware error status is non-zero, plus the error number.

Physics advances through :meth:`ServoBusEmulator.step` (the caller keeps real time).
"""

from __future__ import annotations

import random
from collections.abc import Sequence
from dataclasses import dataclass, field

from sim.dynamixel_packets import Packet, build_status
from sim.servo_emulator import EmulatedServo
from sim.servo_emulator_physics import ServoPhysics
from teleop.devices import dynamixel_tables as T


@dataclass(frozen=True, slots=True)
class FaultConfig:
    """Faults to inject (all off by default)."""

    drop_rate: float = 0.0  # probability that a due reply is not sent
    corrupt_rate: float = 0.0  # probability that a reply's checksum/CRC is wrong
    latency_s: float = 0.0  # extra delay before each reply
    overload_ids: tuple[int, ...] = ()  # servos reporting the overload error bit
    overheat_ids: tuple[int, ...] = ()  # servos reporting overheat (and 85 deg C)
    seed: int = 0
    voltage_ids: tuple[int, ...] = ()  # servos reporting the input voltage error bit


@dataclass(frozen=True, slots=True)
class Reply:
    """A status packet to send after ``delay_s``."""

    data: bytes
    delay_s: float = 0.0


@dataclass(slots=True)
class BusCounters:
    """What the emulator has seen and done."""

    packets: int = 0
    bad_checksums: int = 0
    replies: int = 0
    dropped: int = 0
    corrupted: int = 0
    by_instruction: dict[int, int] = field(default_factory=dict)


def _u16(b: bytes, i: int) -> int:
    return b[i] | (b[i + 1] << 8)


class ServoBusEmulator:
    """Up to four emulated servos on one bus, moving ``physics``."""

    def __init__(self, protocol: int, ids: Sequence[int], physics: ServoPhysics,
                 homes_counts: Sequence[int], inversions: Sequence[int],
                 faults: FaultConfig = FaultConfig(), return_delay_us: int = 0) -> None:
        if protocol not in (1, 2):
            raise ValueError(f"protocol must be 1 or 2, got {protocol}")
        if not 1 <= len(ids) <= 4 or len(set(ids)) != len(ids):
            raise ValueError(f"need 1..4 distinct servo IDs, got {list(ids)}")
        self.protocol = protocol
        self.servos = [EmulatedServo(i, protocol, h, inv, return_delay_us)
                       for i, h, inv in zip(ids, homes_counts, inversions, strict=True)]
        self.physics = physics
        self.counters = BusCounters()
        self.faults = faults
        self._drives: list | None = None  # cached physics commands; None after any write
        self._sync_senses()

    # ---- faults (may be changed while running: tests switch them on and off)
    @property
    def faults(self) -> FaultConfig:
        return self._faults

    @faults.setter
    def faults(self, faults: FaultConfig) -> None:
        self._faults = faults
        self._rng = random.Random(faults.seed)
        for s in self.servos:
            bits = 0
            if s.dxl_id in faults.overload_ids:
                bits |= T.P1_ERR_OVERLOAD if self.protocol == 1 else T.P2_HW_OVERLOAD
            if s.dxl_id in faults.overheat_ids:
                bits |= T.P1_ERR_OVERHEAT if self.protocol == 1 else T.P2_HW_OVERHEAT
            if s.dxl_id in faults.voltage_ids:
                bits |= T.P1_ERR_VOLTAGE if self.protocol == 1 else T.P2_HW_VOLTAGE
            s.set_condition(bits)
        self._stale = True  # registers (temperature, hardware error status) follow

    # ---- physics
    def step(self, dt_s: float, steps: int = 1) -> None:
        """Advance the physics by ``steps`` steps of ``dt_s`` under the present control
        tables."""
        if self._drives is None:
            self._drives = [s.drive() for s in self.servos]
        self.physics.step(self._drives, dt_s, steps)
        self._stale = True

    def _sync_senses(self) -> None:
        """Copy the physics' measurements into the present-value registers."""
        for servo, sense in zip(self.servos, self.physics.sense(), strict=True):
            servo.sense(sense)
        self._stale = False
        self._drives = None  # an alarm shutdown may have switched the torque off

    # ---- packets
    def _servo(self, dxl_id: int) -> EmulatedServo | None:
        for s in self.servos:
            if s.dxl_id == dxl_id:
                return s
        return None

    def handle(self, pkt: Packet) -> list[Reply]:
        """The replies to one instruction packet."""
        if self._stale:
            self._sync_senses()
        self._drives = None
        c = self.counters
        c.packets += 1
        c.by_instruction[pkt.instruction] = c.by_instruction.get(pkt.instruction, 0) + 1
        if not pkt.checksum_ok:
            c.bad_checksums += 1
            servo = self._servo(pkt.dxl_id)
            if servo is None or servo.peek("status_return_level") < 2:
                return []
            err = T.P1_ERR_CHECKSUM if self.protocol == 1 else T.P2_ERR_CRC
            return self._emit([(servo, err, b"", 2)])
        i = pkt.instruction
        if i == T.INST_SYNC_WRITE:
            self._sync_write(pkt.params)
            return []
        if i == T.INST_SYNC_READ and self.protocol == 2:
            return self._emit(self._sync_read(pkt.params))
        if i == T.INST_BULK_READ and self.protocol == 1:
            return self._emit(self._bulk_read_v1(pkt.params))
        if pkt.dxl_id == T.BROADCAST_ID:
            results = [self._unicast(s, pkt) for s in self.servos]
            if i == T.INST_PING and self.protocol == 2:
                return self._emit([r for r in results if r is not None])
            return []
        servo = self._servo(pkt.dxl_id)
        if servo is None:
            return []
        result = self._unicast(servo, pkt)
        return self._emit([result] if result is not None else [])

    def _unicast(self, s: EmulatedServo, pkt: Packet) -> tuple[EmulatedServo, int, bytes, int]:
        """(servo, instruction error, params, needed return level) for one servo."""
        p, i, v1 = pkt.params, pkt.instruction, self.protocol == 1
        bad_instr = T.P1_ERR_INSTRUCTION if v1 else T.P2_ERR_INSTRUCTION
        bad_length = T.P1_ERR_RANGE if v1 else T.P2_ERR_DATA_LENGTH
        if i == T.INST_PING:
            data = b"" if v1 else bytes([s.mem[0], s.mem[1], s.mem[6]])
            return s, 0, data, 0
        if i == T.INST_READ:
            if len(p) != (2 if v1 else 4):
                return s, bad_length, b"", 1
            addr, n = (p[0], p[1]) if v1 else (_u16(p, 0), _u16(p, 2))
            data, ok = s.read(addr, n)
            return s, 0 if ok else bad_length, data, 1
        if i in (T.INST_WRITE, T.INST_REG_WRITE):
            if len(p) < (2 if v1 else 3):
                return s, bad_length, b"", 2
            addr, data = (p[0], p[1:]) if v1 else (_u16(p, 0), p[2:])
            if i == T.INST_WRITE:
                return s, s.write(addr, bytes(data)), b"", 2
            s.pending = (addr, bytes(data))
            s.poke("registered" if v1 else "registered_instruction", 1)
            return s, 0, b"", 2
        if i == T.INST_REBOOT and not v1:
            s.reboot()
            self._stale = True  # the hardware error status register follows
            return s, 0, b"", 2
        if i == T.INST_ACTION:
            if s.pending is None:
                return s, bad_instr, b"", 2
            addr, data = s.pending
            s.pending = None
            s.poke("registered" if v1 else "registered_instruction", 0)
            return s, s.write(addr, data), b"", 2
        return s, bad_instr, b"", 2

    def _sync_write(self, p: bytes) -> None:
        v1 = self.protocol == 1
        head = 2 if v1 else 4
        if len(p) < head:
            return
        addr, n = (p[0], p[1]) if v1 else (_u16(p, 0), _u16(p, 2))
        block = 1 + n
        for k in range(head, len(p) - block + 1, block):
            servo = self._servo(p[k])
            if servo is not None:
                servo.write(addr, bytes(p[k + 1:k + block]))

    def _sync_read(self, p: bytes) -> list[tuple[EmulatedServo, int, bytes, int]]:
        if len(p) < 5:
            return []
        addr, n = _u16(p, 0), _u16(p, 2)
        out = []
        for dxl_id in p[4:]:
            servo = self._servo(dxl_id)
            if servo is not None:
                data, ok = servo.read(addr, n)
                out.append((servo, 0 if ok else T.P2_ERR_DATA_LENGTH, data, 1))
        return out

    def _bulk_read_v1(self, p: bytes) -> list[tuple[EmulatedServo, int, bytes, int]]:
        out = []
        for k in range(1, len(p) - 2, 3):  # p[0] is 0x00; then (length, id, address)
            n, dxl_id, addr = p[k], p[k + 1], p[k + 2]
            servo = self._servo(dxl_id)
            if servo is not None:
                data, ok = servo.read(addr, n)
                out.append((servo, 0 if ok else T.P1_ERR_RANGE, data, 1))
        return out

    def _emit(self, results: list[tuple[EmulatedServo, int, bytes, int]]) -> list[Reply]:
        """Build status packets, applying the return level and the injected faults."""
        f, c = self._faults, self.counters
        replies = []
        for servo, err, data, level in results:
            if servo.peek("status_return_level") < level:
                continue
            if f.drop_rate > 0 and self._rng.random() < f.drop_rate:
                c.dropped += 1
                continue
            raw = bytearray(build_status(self.protocol, servo.dxl_id, servo.status_error(err),
                                         data))
            if f.corrupt_rate > 0 and self._rng.random() < f.corrupt_rate:
                raw[-1] ^= 0x5A
                c.corrupted += 1
            c.replies += 1
            replies.append(Reply(bytes(raw), servo.return_delay_s + f.latency_s))
        return replies
