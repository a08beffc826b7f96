"""Protocol 2.0 codec: golden bytes, CRC, stuffing, round trips, and a fuzzed frame reader."""

from __future__ import annotations

import random

import pytest
from dynamixel_sdk.protocol2_packet_handler import Protocol2PacketHandler

from drivers.errors import ProtocolError
from drivers.protocol import (
    Instruction,
    Packet,
    PacketReader,
    add_stuffing,
    crc16,
    decode_fast_sync_status,
    decode_packet,
    encode_fast_sync_status,
    encode_packet,
    encode_status,
    read_params,
    remove_stuffing,
    sync_read_params,
    sync_write_params,
    wire_time_s,
    write_params,
)

# e-manual "Protocol 2.0" examples
PING_ID1 = bytes.fromhex("FF FF FD 00 01 03 00 01 19 4E")
READ_ID1_132_4 = bytes.fromhex("FF FF FD 00 01 07 00 02 84 00 04 00 1D 15")


def test_that_ping_packet_matches_the_e_manual_bytes() -> None:
    assert encode_packet(1, Instruction.PING) == PING_ID1


def test_that_read_packet_matches_the_e_manual_bytes() -> None:
    assert encode_packet(1, Instruction.READ, read_params(132, 4)) == READ_ID1_132_4


def test_that_crc_agrees_with_dynamixel_sdk_on_random_data() -> None:
    sdk = Protocol2PacketHandler()
    rng = random.Random(1)
    for _ in range(200):
        data = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 80)))
        assert crc16(data) == sdk.updateCRC(0, list(data), len(data))


def test_that_stuffing_inserts_fd_after_ff_ff_fd_and_round_trips() -> None:
    body = b"\x03\xff\xff\xfd\x01"
    assert add_stuffing(body) == b"\x03\xff\xff\xfd\xfd\x01"
    assert remove_stuffing(add_stuffing(body)) == body


def test_that_encode_then_decode_round_trips_random_packets() -> None:
    rng = random.Random(2)
    for _ in range(500):
        params = bytes(rng.choice([0xFF, 0xFD, rng.randrange(256)]) for _ in range(rng.randrange(0, 40)))
        packet = Packet(rng.randrange(0, 253), rng.choice(list(Instruction)), params)
        assert decode_packet(encode_packet(packet.servo_id, packet.instruction, packet.params)) == packet


def test_that_a_flipped_bit_is_caught_by_the_crc() -> None:
    frame = bytearray(encode_packet(3, Instruction.WRITE, write_params(116, b"\x00\x08\x00\x00")))
    frame[9] ^= 0x10
    with pytest.raises(ProtocolError, match="CRC"):
        decode_packet(bytes(frame))


def test_that_status_packet_carries_error_byte_and_data() -> None:
    p = decode_packet(encode_status(7, 0x80 | 4, b"\x01\x02"))
    assert (p.servo_id, p.error, p.data, p.is_status) == (7, 0x84, b"\x01\x02", True)


def test_that_sync_write_params_reject_a_wrong_data_size() -> None:
    with pytest.raises(ProtocolError, match="id 2"):
        sync_write_params(116, 4, {1: b"\x00" * 4, 2: b"\x00" * 3})


def test_that_fast_sync_status_round_trips_and_has_the_documented_size() -> None:
    blocks = [(i, 0x80 if i == 2 else 0, bytes([i] * 10)) for i in (1, 2, 3)]
    frame = encode_fast_sync_status(blocks)
    assert len(frame) == 8 + 3 * (4 + 10)
    out = decode_fast_sync_status(frame, 10, [1, 2, 3])
    assert out[2] == (0x80, bytes([2] * 10))


def test_that_fast_sync_status_decodes_with_dynamixel_sdk_crc_check() -> None:
    frame = encode_fast_sync_status([(1, 0, b"\x01\x02"), (2, 0, b"\x03\x04")])
    sdk = Protocol2PacketHandler()
    assert sdk.updateCRC(0, list(frame), len(frame) - 2) == frame[-2] | (frame[-1] << 8)


def test_that_reader_finds_frames_among_garbage_and_split_reads() -> None:
    a = encode_packet(1, Instruction.PING)
    b = encode_status(2, 0, b"\xaa")
    stream = b"\x00\xff\x12" + a + b"\xff\xff" + b
    reader = PacketReader()
    got = []
    for k in range(0, len(stream), 3):
        reader.feed(stream[k : k + 3])
        while (f := reader.next_frame()) is not None:
            got.append(f)
    assert got == [a, b]


def test_that_reader_never_crashes_and_never_yields_a_bad_crc_frame_on_random_bytes() -> None:
    rng = random.Random(3)
    reader = PacketReader()
    for _ in range(300):
        chunk = bytes(rng.choice([0xFF, 0xFD, 0x00, rng.randrange(256)]) for _ in range(rng.randrange(1, 64)))
        reader.feed(chunk)
        while (f := reader.next_frame()) is not None:
            decode_packet(f)  # anything yielded must decode


def test_that_sync_read_request_for_20_servos_is_34_bytes_on_the_wire() -> None:
    frame = encode_packet(0xFE, Instruction.SYNC_READ, sync_read_params(126, 10, list(range(1, 21))))
    assert len(frame) == 34
    assert wire_time_s(len(frame), 1_000_000) == pytest.approx(340e-6)
