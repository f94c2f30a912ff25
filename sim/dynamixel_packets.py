"""Dynamixel packet building and parsing, Protocol 1.0 and 2.0 (independent of dynamixel-sdk).

Protocol 1.0::

    FF FF ID LEN INSTR/ERR PARAM... CHECKSUM
    LEN = n_params + 2, CHECKSUM = ~sum(ID .. last param) & 0xFF

Protocol 2.0::

    FF FF FD 00 ID LEN_L LEN_H INSTR [ERR] PARAM... CRC_L CRC_H
    LEN = bytes after LEN_H (instruction, params, CRC) after byte stuffing;
    CRC-16 (poly 0x8005, init 0, no reflection) over everything before the CRC;
    byte stuffing: in the instruction/params, every FF FF FD is followed by an extra FD.

The CRC here is computed bit by bit from the polynomial, so tests comparing it with the SDK's
table-driven CRC check two independent implementations.
"""

from __future__ import annotations

from dataclasses import dataclass

HEADER1 = b"\xff\xff"
HEADER2 = b"\xff\xff\xfd\x00"
STATUS_INSTR = 0x55


@dataclass(frozen=True, slots=True)
class Packet:
    """One parsed packet: an instruction (to a servo) or a status (from a servo)."""

    protocol: int  # 1 or 2
    dxl_id: int
    instruction: int  # the instruction; 0x55 for a Protocol 2.0 status
    params: bytes  # parameters (for a status: after the error byte)
    error: int = 0  # status packets only
    checksum_ok: bool = True


def checksum_v1(body: bytes | bytearray) -> int:
    """Protocol 1.0 checksum of ``body`` (ID .. last parameter)."""
    return (~sum(body)) & 0xFF


def crc16(data: bytes | bytearray, crc: int = 0) -> int:
    """CRC-16/BUYPASS (poly 0x8005, init 0, MSB first), as Dynamixel Protocol 2.0 uses."""
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) if crc & 0x8000 else (crc << 1)
            crc &= 0xFFFF
    return crc


def stuff(payload: bytes | bytearray) -> bytes:
    """Insert an FD after every FF FF FD in ``payload`` (instruction + params)."""
    out = bytearray()
    for b in payload:
        out.append(b)
        if b == 0xFD and len(out) >= 3 and out[-3] == 0xFF and out[-2] == 0xFF:
            out.append(0xFD)
    return bytes(out)


def unstuff(payload: bytes | bytearray) -> bytes:
    """Remove the FD inserted by :func:`stuff`."""
    out = bytearray()
    i = 0
    while i < len(payload):
        b = payload[i]
        out.append(b)
        if (b == 0xFD and len(out) >= 3 and out[-3] == 0xFF and out[-2] == 0xFF
                and i + 1 < len(payload) and payload[i + 1] == 0xFD):
            i += 1  # skip the stuffed FD
        i += 1
    return bytes(out)


def build_v1(dxl_id: int, instr_or_error: int, params: bytes | bytearray = b"") -> bytes:
    """A Protocol 1.0 packet (instruction or status: same layout)."""
    body = bytes([dxl_id, len(params) + 2, instr_or_error]) + bytes(params)
    return HEADER1 + body + bytes([checksum_v1(body)])


def build_v2(dxl_id: int, instruction: int, params: bytes | bytearray = b"") -> bytes:
    """A Protocol 2.0 instruction packet, stuffed, with CRC."""
    payload = stuff(bytes([instruction]) + bytes(params))
    length = len(payload) + 2
    head = HEADER2 + bytes([dxl_id, length & 0xFF, length >> 8])
    crc = crc16(head + payload)
    return head + payload + bytes([crc & 0xFF, crc >> 8])


def build_status_v2(dxl_id: int, error: int, params: bytes | bytearray = b"") -> bytes:
    """A Protocol 2.0 status packet (instruction 0x55, error byte, params)."""
    return build_v2(dxl_id, STATUS_INSTR, bytes([error]) + bytes(params))


def build_status(protocol: int, dxl_id: int, error: int, params: bytes | bytearray = b"") -> bytes:
    """A status packet in either protocol."""
    if protocol == 1:
        return build_v1(dxl_id, error, params)
    return build_status_v2(dxl_id, error, params)


class PacketReader:
    """Incremental parser of a byte stream into packets (one protocol per reader).

    Garbage before a header is skipped.  A packet whose checksum/CRC is wrong is returned with
    ``checksum_ok=False`` (a servo answers those with a checksum/CRC error).  ``status=True``
    parses status packets (the error byte is split off), otherwise instruction packets.
    """

    def __init__(self, protocol: int, *, status: bool = False) -> None:
        if protocol not in (1, 2):
            raise ValueError(f"protocol must be 1 or 2, got {protocol}")
        self.protocol = protocol
        self.status = status
        self._buf = bytearray()

    def feed(self, data: bytes | bytearray) -> list[Packet]:
        """Add ``data``; return every complete packet now available."""
        self._buf.extend(data)
        out: list[Packet] = []
        while True:
            pkt = self._next_v1() if self.protocol == 1 else self._next_v2()
            if pkt is None:
                return out
            out.append(pkt)

    def _sync(self, header: bytes) -> bool:
        """Drop bytes before the header; True when the header starts the buffer."""
        idx = self._buf.find(header)
        if idx < 0:
            keep = len(header) - 1  # a header may be split across reads
            del self._buf[: max(0, len(self._buf) - keep)]
            return False
        del self._buf[:idx]
        return True

    def _next_v1(self) -> Packet | None:
        while self._sync(HEADER1):
            # FF FF FF ... : the first FF is noise (IDs never reach 0xFF)
            if len(self._buf) >= 3 and self._buf[2] == 0xFF:
                del self._buf[0]
                continue
            if len(self._buf) < 4:
                return None
            length = self._buf[3]
            if length < 2:
                del self._buf[:2]
                continue
            total = 4 + length
            if len(self._buf) < total:
                return None
            raw = bytes(self._buf[:total])
            del self._buf[:total]
            ok = checksum_v1(raw[2:-1]) == raw[-1]
            kind = raw[4]
            params = raw[5:-1]
            if self.status:
                return Packet(1, raw[2], STATUS_INSTR, params, error=kind, checksum_ok=ok)
            return Packet(1, raw[2], kind, params, checksum_ok=ok)
        return None

    def _next_v2(self) -> Packet | None:
        while self._sync(HEADER2[:3]):
            if len(self._buf) < 7:
                return None
            if self._buf[3] != 0x00:  # FF FF FD FD is stuffing, not a header
                del self._buf[:3]
                continue
            length = self._buf[5] | (self._buf[6] << 8)
            if length < 3:
                del self._buf[:3]
                continue
            total = 7 + length
            if len(self._buf) < total:
                return None
            raw = bytes(self._buf[:total])
            del self._buf[:total]
            crc = raw[-2] | (raw[-1] << 8)
            ok = crc16(raw[:-2]) == crc
            payload = unstuff(raw[7:-2])
            instr = payload[0]
            if self.status:
                err = payload[1] if len(payload) > 1 else 0
                return Packet(2, raw[4], instr, payload[2:], error=err, checksum_ok=ok)
            return Packet(2, raw[4], instr, payload[1:], checksum_ok=ok)
        return None
