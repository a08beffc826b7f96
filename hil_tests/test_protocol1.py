"""Protocol 1.0 framing: golden bytes from the e-manual's examples, the reader, parameter layouts."""

from __future__ import annotations

import pytest

from drivers.errors import ProtocolError
from drivers.protocol import Instruction
from drivers.protocol1 import (
    ErrorBits1,
    Instruction1,
    PacketReader1,
    bulk_read_params1,
    checksum,
    decode_instruction1,
    decode_status1,
    describe_error1,
    encode_instruction1,
    encode_status1,
    parse_bulk_read_params1,
    read_params1,
    sync_write_params1,
    write_params1,
)


def test_that_ping_read_and_status_frames_match_the_e_manual_examples() -> None:
    # e-manual Protocol 1.0: PING id 1, its status, READ of the temperature (0x2B, 1 byte)
    assert encode_instruction1(1, Instruction1.PING) == bytes.fromhex("ffff010201fb")
    assert encode_status1(1, 0) == bytes.fromhex("ffff010200fc")
    assert encode_instruction1(1, Instruction1.READ, read_params1(0x2B, 1)) == bytes.fromhex("ffff0104022b01cc")
    assert encode_status1(1, 0, b"\x20") == bytes.fromhex("ffff01030020db")
    # broadcast WRITE of ID = 1
    assert encode_instruction1(0xFE, Instruction1.WRITE, write_params1(3, b"\x01")) == bytes.fromhex("fffffe04030301f6")


def test_that_sync_write_matches_the_e_manual_example() -> None:
    data = {0: bytes.fromhex("10005001"), 1: bytes.fromhex("20026003"), 2: bytes.fromhex("30007001"),
            3: bytes.fromhex("20028003")}
    frame = encode_instruction1(0xFE, Instruction1.SYNC_WRITE, sync_write_params1(0x1E, 4, data))
    assert frame == bytes.fromhex("fffffe18831e040010005001012002600302300070010320028003" + "12")


def test_that_a_status_decodes_like_a_2_0_status_with_the_error_byte_first() -> None:
    p = decode_status1(encode_status1(7, ErrorBits1.OVERLOAD | ErrorBits1.OVERHEATING, b"\x01\x02"))
    assert (p.servo_id, p.instruction, p.is_status) == (7, Instruction.STATUS, True)
    assert p.error == 0x24 and p.data == b"\x01\x02"
    q = decode_instruction1(encode_instruction1(3, Instruction1.WRITE, b"\x1e\x00\x02"))
    assert (q.servo_id, q.instruction, q.params) == (3, Instruction1.WRITE, b"\x1e\x00\x02")


def test_that_bad_frames_are_refused_with_the_reason() -> None:
    good = encode_status1(1, 0, b"\x05")
    with pytest.raises(ProtocolError, match="checksum"):
        decode_status1(good[:-1] + bytes((good[-1] ^ 1,)))
    with pytest.raises(ProtocolError, match="length"):
        decode_status1(good[:3] + bytes((5,)) + good[4:])
    with pytest.raises(ProtocolError, match="header"):
        decode_status1(b"\xfe" + good[1:])
    with pytest.raises(ProtocolError, match="one byte"):
        read_params1(300, 2)


def test_that_the_reader_skips_garbage_and_corrupt_frames_and_splits_what_follows() -> None:
    a, b = encode_status1(1, 0, b"\x10\x20"), encode_status1(2, 0x20, b"\x30\x40")
    corrupt = bytearray(encode_status1(3, 0, b"\x00\x00"))
    corrupt[5] ^= 0x40
    reader = PacketReader1()
    stream = b"\x00\x13\xff" + a + bytes(corrupt) + b
    for k in range(0, len(stream), 3):  # arriving in pieces
        reader.feed(stream[k : k + 3])
    frames = []
    while (f := reader.next_frame()) is not None:
        frames.append(f)
    assert frames == [a, b]
    assert reader.crc_errors == 1 and reader.skipped_bytes >= 3


def test_that_the_checksum_is_the_inverted_low_byte_of_the_sum() -> None:
    assert checksum(b"\x01\x02\x01") == 0xFB
    assert checksum(bytes(range(1, 200))) == (~sum(range(1, 200))) & 0xFF


def test_that_bulk_read_parameters_round_trip() -> None:
    items = [(1, 36, 8), (2, 30, 2), (9, 43, 1)]
    params = bulk_read_params1(items)
    assert params == bytes((0, 8, 1, 36, 2, 2, 30, 1, 9, 43))
    assert parse_bulk_read_params1(params) == items
    with pytest.raises(ProtocolError):
        parse_bulk_read_params1(params[1:])


def test_that_error_bytes_are_described_as_refusals_and_alarms() -> None:
    assert describe_error1(0) == "ok"
    assert describe_error1(ErrorBits1.RANGE | ErrorBits1.OVERLOAD) == "range error, overload alarm"
    assert ErrorBits1.describe(0x25) == "input voltage, overheating, overload"
