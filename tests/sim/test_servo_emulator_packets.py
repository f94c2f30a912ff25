"""Dynamixel packet building/parsing against known vectors from the protocol specs."""

from __future__ import annotations

import random

import pytest
from dynamixel_sdk import Protocol2PacketHandler

from sim.dynamixel_packets import (
    PacketReader,
    build_status,
    build_v1,
    build_v2,
    checksum_v1,
    crc16,
    stuff,
    unstuff,
)


def test_checksum_v1_manual_example() -> None:
    # MX-28 manual: READ ID 1, address 0x2B (present temperature), 1 byte
    assert build_v1(1, 0x02, bytes([0x2B, 0x01])) == bytes.fromhex("FFFF0104022B01CC")
    # PING ID 1: ~(1 + 2 + 1) & 0xFF = 0xFB
    assert build_v1(1, 0x01) == bytes.fromhex("FFFF010201FB")
    assert checksum_v1(bytes([0xFE, 0x04, 0x03, 0x03, 0x01])) == (~0x109) & 0xFF


def test_crc16_check_value_and_manual_ping() -> None:
    # CRC-16/BUYPASS catalog check value (poly 0x8005, init 0, no reflection)
    assert crc16(b"123456789") == 0xFEE8
    # Protocol 2.0 manual: PING ID 1 = FF FF FD 00 01 03 00 01 19 4E
    assert build_v2(1, 0x01) == bytes.fromhex("FFFFFD0001030001194E")


def test_crc16_matches_the_sdk_table_implementation() -> None:
    rng = random.Random(3)
    sdk = Protocol2PacketHandler()
    for n in (1, 7, 64, 300):
        data = bytes(rng.randrange(256) for _ in range(n))
        assert crc16(data) == sdk.updateCRC(0, list(data), len(data))


def test_byte_stuffing_inserts_fd_after_ff_ff_fd_and_round_trips() -> None:
    payload = bytes([0x03, 0x74, 0x00, 0xFF, 0xFF, 0xFD, 0x01])
    assert stuff(payload) == bytes([0x03, 0x74, 0x00, 0xFF, 0xFF, 0xFD, 0xFD, 0x01])
    assert unstuff(stuff(payload)) == payload
    rng = random.Random(5)
    for _ in range(200):
        p = bytes(rng.choice([0xFF, 0xFD, 0x00, 0x12]) for _ in range(rng.randrange(1, 20)))
        assert unstuff(stuff(p)) == p


def test_stuffed_packet_matches_the_sdk() -> None:
    # WRITE to ID 1 whose data contains FF FF FD: the SDK stuffs and sets the CRC on send
    params = [0x74, 0x00, 0xFF, 0xFF, 0xFD, 0x00]
    mine = build_v2(1, 0x03, bytes(params))
    sdk = Protocol2PacketHandler()
    pkt = [0xFF, 0xFF, 0xFD, 0x00, 1, len(params) + 3, 0, 0x03, *params, 0, 0]
    pkt = sdk.addStuffing(pkt)
    total = pkt[5] + 7
    crc = sdk.updateCRC(0, pkt, total - 2)
    pkt[total - 2], pkt[total - 1] = crc & 0xFF, crc >> 8
    assert mine == bytes(pkt[:total])
    assert mine[5] == len(params) + 3 + 1  # length counts the stuffed byte


@pytest.mark.parametrize("protocol", [1, 2])
def test_reader_resyncs_splits_and_flags_bad_checksums(protocol: int) -> None:
    build = build_v1 if protocol == 1 else build_v2
    a = build(3, 0x02, bytes([36, 8]) if protocol == 1 else bytes([132, 0, 4, 0]))
    b = bytearray(build(4, 0x01))
    b[-1] ^= 0x01  # corrupt
    stream = b"\x00\x12\xff" + a + bytes(b)
    reader = PacketReader(protocol)
    got = []
    for i in range(0, len(stream), 3):  # fed in small chunks
        got += reader.feed(stream[i:i + 3])
    assert [(p.dxl_id, p.instruction, p.checksum_ok) for p in got] == [(3, 2, True),
                                                                       (4, 1, False)]
    assert got[0].params == (bytes([36, 8]) if protocol == 1 else bytes([132, 0, 4, 0]))


@pytest.mark.parametrize("protocol", [1, 2])
def test_status_packets_parse_with_error_byte(protocol: int) -> None:
    raw = build_status(protocol, 2, 0x20, bytes([0xFF, 0xFF, 0xFD, 0x07]))
    (pkt,) = PacketReader(protocol, status=True).feed(raw)
    assert (pkt.dxl_id, pkt.error, pkt.params, pkt.checksum_ok) == (
        2, 0x20, bytes([0xFF, 0xFF, 0xFD, 0x07]), True)
