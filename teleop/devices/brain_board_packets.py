"""The ReFlex TakkTile brain board's UDP packets: pure encoding, decoding and validation.

Facts (reference: reflex-hardware.md, "Brain board"):

* PC -> board: set modes ``[1, m0, m1, m2, m3]`` (0 idle, 1 velocity, 2 position) and set
  targets ``[2, t0_hi, t0_lo, ..., t3_hi, t3_lo]`` (four uint16, big-endian).
* Board -> PC, about every 25 ms: one packed little-endian struct of 202 bytes (a firmware
  may append 44 bytes of palm data, accepted and ignored): header[4] (header[0] = 1),
  uint32 systime_us, uint16 pressures[38], uint16 temperatures[38], uint16 encoders[3],
  uint8 dxl_error[4], uint16 dxl_angle[4], dxl_speed[4], dxl_load[4], uint8 dxl_voltage[4],
  dxl_temperature[4].

:func:`decode_state` raises :class:`~teleop.errors.DecodeError` with one of
:data:`STATE_REASONS`; :class:`StateReceiver` wraps it for the control loop: it never raises,
also drops a board time that does not move forward (a duplicate or reordered packet), and
counts every drop by reason as the zenoh decoder does
(:class:`~teleop.transport.safe_decoder.SafeDecoder`).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from teleop.errors import DecodeError
from teleop.transport.safe_decoder import RejectCounts, SafeDecoder

MULTICAST_GROUP = "224.0.0.124"
PORT = 11333
STATE_MAGIC = 1
MODES_TYPE = 1
TARGETS_TYPE = 2
N_MOTORS = 4
N_TACTILE = 38  # 9 per finger in finger order, then 11 unused palm slots
N_ENCODERS = 3
MODE_IDLE, MODE_VELOCITY, MODE_POSITION = 0, 1, 2

_STATE = struct.Struct("<4BI38H38H3H4B4H4H4H4B4B")
STATE_LEN = _STATE.size  # 202
PALM_LEN = 44
MODES_LEN = 1 + N_MOTORS
TARGETS_LEN = 1 + 2 * N_MOTORS
_TARGETS = struct.Struct(">B4H")

#: Every reason :func:`decode_state` raises, plus the receiver's own ``stale_time``.
STATE_REASONS: tuple[str, ...] = ("not_bytes", "bad_length", "bad_magic", "stale_time")
#: Every reason :func:`decode_command` raises.
COMMAND_REASONS: tuple[str, ...] = ("not_bytes", "bad_length", "unknown_type", "bad_mode")

_U32 = 1 << 32


@dataclass(frozen=True, slots=True)
class BoardState:
    """One state packet, raw fields as on the wire (conversions live in the backend)."""

    header: tuple[int, int, int, int]
    systime_us: int
    pressures: tuple[int, ...]  # N_TACTILE
    temperatures: tuple[int, ...]  # N_TACTILE
    encoders: tuple[int, int, int]  # proximal AS5048A, 14 bit
    dxl_error: tuple[int, int, int, int]
    dxl_angle: tuple[int, int, int, int]  # uint16 on the wire (a negative angle wraps)
    dxl_speed: tuple[int, int, int, int]
    dxl_load: tuple[int, int, int, int]
    dxl_voltage: tuple[int, int, int, int]
    dxl_temperature: tuple[int, int, int, int]


@dataclass(frozen=True, slots=True)
class ModesPacket:
    """PC -> board: the control mode of each motor."""

    modes: tuple[int, int, int, int]


@dataclass(frozen=True, slots=True)
class TargetsPacket:
    """PC -> board: raw goal positions (position mode) or moving speeds (velocity mode)."""

    targets: tuple[int, int, int, int]


def encode_state(s: BoardState) -> bytes:
    """The 202-byte wire form of ``s`` (every field must fit its type: ``struct.error``)."""
    return _STATE.pack(*s.header, s.systime_us, *s.pressures, *s.temperatures, *s.encoders,
                       *s.dxl_error, *s.dxl_angle, *s.dxl_speed, *s.dxl_load, *s.dxl_voltage,
                       *s.dxl_temperature)


def decode_state(data: object) -> BoardState:
    """Parse one state packet; :class:`DecodeError` (length, magic byte) if it is not one."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise DecodeError("not_bytes", type(data).__name__)
    n = len(data)
    if n not in (STATE_LEN, STATE_LEN + PALM_LEN):
        raise DecodeError("bad_length", f"{n} bytes, expected {STATE_LEN} "
                          f"(or {STATE_LEN + PALM_LEN} with palm data)")
    v = _STATE.unpack_from(bytes(data[:STATE_LEN]))
    if v[0] != STATE_MAGIC:
        raise DecodeError("bad_magic", f"header[0] = {v[0]}, expected {STATE_MAGIC}")
    i = 5
    fields: list[tuple[int, ...]] = []
    for size in (N_TACTILE, N_TACTILE, N_ENCODERS, 4, 4, 4, 4, 4, 4):
        fields.append(tuple(v[i:i + size]))
        i += size
    return BoardState(tuple(v[:4]), v[4], *fields)  # type: ignore[arg-type]


def encode_modes(modes: tuple[int, int, int, int]) -> bytes:
    """``[1, m0, m1, m2, m3]``."""
    if len(modes) != N_MOTORS or any(m not in (0, 1, 2) for m in modes):
        raise ValueError(f"modes must be 4 values of 0, 1 or 2, got {modes}")
    return bytes((MODES_TYPE, *modes))


def encode_targets(targets: tuple[int, int, int, int]) -> bytes:
    """``[2, t0_hi, t0_lo, ...]`` (uint16 big-endian; ``struct.error`` when out of range)."""
    if len(targets) != N_MOTORS:
        raise ValueError(f"need {N_MOTORS} targets, got {len(targets)}")
    return _TARGETS.pack(TARGETS_TYPE, *targets)


def decode_command(data: object) -> ModesPacket | TargetsPacket:
    """Parse a PC -> board packet (the emulator's side); :class:`DecodeError` if bad."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise DecodeError("not_bytes", type(data).__name__)
    b = bytes(data)
    if not b:
        raise DecodeError("bad_length", "empty packet")
    if b[0] == MODES_TYPE:
        if len(b) != MODES_LEN:
            raise DecodeError("bad_length", f"modes packet of {len(b)} bytes, expected "
                              f"{MODES_LEN}")
        modes = tuple(b[1:])
        if any(m > MODE_POSITION for m in modes):
            raise DecodeError("bad_mode", f"modes {list(modes)}")
        return ModesPacket(modes)  # type: ignore[arg-type]
    if b[0] == TARGETS_TYPE:
        if len(b) != TARGETS_LEN:
            raise DecodeError("bad_length", f"targets packet of {len(b)} bytes, expected "
                              f"{TARGETS_LEN}")
        return TargetsPacket(tuple(_TARGETS.unpack(b)[1:]))  # type: ignore[arg-type]
    raise DecodeError("unknown_type", f"first byte {b[0]}")


def board_time_advanced(last_us: int | None, now_us: int) -> bool:
    """Whether ``now_us`` is after ``last_us`` on the board's wrapping uint32 clock (a
    forward step of less than half the range; equal or backwards is not)."""
    if last_us is None:
        return True
    step = (now_us - last_us) % _U32
    return 0 < step < _U32 // 2


class StateReceiver:
    """Validates state packets for the control loop: never raises, counts drops by reason.

    A packet whose board time does not move forward is dropped as ``stale_time``.  A board
    that restarted (its clock jumps back and then runs on) is followed again after
    ``resync_after`` consecutive stale packets that advance among themselves (``resyncs``
    counts those).
    """

    def __init__(self, name: str = "brain board", resync_after: int = 4) -> None:
        self._drops = SafeDecoder(name)
        self.resync_after = resync_after
        self.accepted = 0
        self.resyncs = 0
        self.last_time_us: int | None = None
        self._stale_run: list[int] = []

    def accept(self, data: object) -> BoardState | None:
        """The packet's state, or None (counted by reason) if it must be dropped."""
        try:
            state = decode_state(data)
        except DecodeError as exc:
            self._drops.reject(exc.reason, exc.detail)
            return None
        except Exception as exc:  # a codec bug must not stop a control loop
            self._drops.reject("internal", f"{type(exc).__name__}: {exc}")
            return None
        t = state.systime_us
        if not board_time_advanced(self.last_time_us, t):
            run = self._stale_run
            if run and not board_time_advanced(run[-1], t):
                run.clear()
            run.append(t)
            if len(run) < self.resync_after:
                self._drops.reject("stale_time", f"board time {t} us after {self.last_time_us}")
                return None
            self.resyncs += 1
        self._stale_run.clear()
        self.last_time_us = t
        self.accepted += 1
        return state

    def counts(self) -> RejectCounts:
        """Accepted packets and drops by reason (a frozen snapshot)."""
        c = self._drops.counts()
        return RejectCounts(self.accepted, c.rejected, c.by_reason)
