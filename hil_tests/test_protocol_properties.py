"""Property tests (hypothesis) of the Protocol 2.0 codec, the CRC and the host's fast paths."""

from __future__ import annotations

import struct

import numpy as np
from dynamixel_sdk.protocol2_packet_handler import Protocol2PacketHandler
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import drivers.mockbus as mb
from drivers.servo_map import BusSpec, ServoMap, ServoSpec
from drivers.bus import DynamixelBus
from drivers.clock import FakeClock
from drivers.group import ServoGroup
from drivers.protocol import (
    BROADCAST_ID,
    Instruction,
    Packet,
    PacketReader,
    crc16_loop,
    add_stuffing,
    crc16,
    decode_fast_sync_status,
    decode_packet,
    encode_fast_sync_status,
    encode_packet,
    remove_stuffing,
    sync_write_params,
)

SETTINGS = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
_SDK = Protocol2PacketHandler()

# bytes biased towards the header / stuffing bytes, where codecs go wrong
tricky_bytes = st.lists(st.one_of(st.sampled_from([0xFF, 0xFD, 0x00]), st.integers(0, 255)),
                        max_size=300).map(bytes)
servo_ids = st.integers(0, 252) | st.just(BROADCAST_ID)
instructions = st.sampled_from([int(i) for i in Instruction])


@SETTINGS
@given(st.binary(max_size=700))
def test_that_crc16_agrees_with_dynamixel_sdk_for_any_bytes(data: bytes) -> None:
    assert crc16(data) == _SDK.updateCRC(0, list(data), len(data))


@SETTINGS
@given(st.binary(max_size=500), st.binary(max_size=500))
def test_that_a_running_crc_continues_over_concatenated_data(a: bytes, b: bytes) -> None:
    assert crc16(b, crc16(a)) == crc16(a + b) == crc16_loop(a + b, 0)


@SETTINGS
@given(st.binary(min_size=2, max_size=600), st.integers(0, 0xFFFF))
def test_that_the_numpy_crc_equals_the_table_loop_from_any_start_value(data: bytes, start: int) -> None:
    assert crc16(data, start) == crc16_loop(data, start)


@SETTINGS
@given(tricky_bytes)
def test_that_stuffing_round_trips_and_leaves_no_bare_header_in_the_body(body: bytes) -> None:
    stuffed = add_stuffing(body)
    assert remove_stuffing(stuffed) == body
    # every FF FF FD in the stuffed body is followed by the stuffing byte FD
    k = stuffed.find(b"\xff\xff\xfd")
    while k >= 0:
        assert stuffed[k + 3 : k + 4] == b"\xfd"
        k = stuffed.find(b"\xff\xff\xfd", k + 4)


@SETTINGS
@given(servo_ids, instructions, tricky_bytes)
def test_that_any_packet_survives_encode_then_decode(servo_id: int, instruction: int, params: bytes) -> None:
    frame = encode_packet(servo_id, instruction, params)
    assert decode_packet(frame) == Packet(servo_id, instruction, params)
    assert frame[:4] == b"\xff\xff\xfd\x00"
    assert frame[5] | (frame[6] << 8) == len(frame) - 7


@SETTINGS
@given(st.lists(st.tuples(servo_ids, instructions, tricky_bytes), min_size=1, max_size=5),
       st.binary(max_size=40).map(lambda b: b.replace(b"\xfd", b"")), st.data())
def test_that_the_reader_finds_every_frame_after_garbage_in_any_chunking(packets, garbage, data) -> None:
    frames = [encode_packet(i, inst, p) for i, inst, p in packets]
    stream = garbage + b"".join(frames)
    cuts = sorted(data.draw(st.lists(st.integers(0, len(stream)), max_size=8)))
    reader = PacketReader(max_length=4096)
    got = []
    for a, b in zip([0, *cuts], [*cuts, len(stream)]):
        reader.feed(stream[a:b])
        while (f := reader.next_frame()) is not None:
            got.append(f)
    assert got == frames


@SETTINGS
@given(tricky_bytes, st.data())
def test_that_any_single_bit_flip_is_caught_and_never_answered(params: bytes, data) -> None:
    frame = bytearray(encode_packet(1, Instruction.WRITE, b"\x41\x00" + params[:20]))
    bit = data.draw(st.integers(0, 8 * len(frame) - 1))
    frame[bit // 8] ^= 1 << (bit % 8)
    bus = mb.MockBus.from_ids([1], clock=FakeClock())
    assert bus.receive(bytes(frame)) == []


@SETTINGS
@given(st.binary(max_size=200))
def test_that_the_emulator_survives_random_bytes_and_answers_only_valid_frames(noise: bytes) -> None:
    bus = mb.MockBus.from_ids([1, 2], clock=FakeClock())
    for reply in bus.receive(noise):
        assert decode_packet(reply.data).is_status


blocks_strategy = st.integers(1, 8).flatmap(lambda n: st.integers(1, 16).flatmap(lambda length: st.tuples(
    st.lists(st.integers(0, 252), min_size=n, max_size=n, unique=True),
    st.lists(st.integers(0, 255), min_size=n, max_size=n),
    st.lists(st.binary(min_size=length, max_size=length), min_size=n, max_size=n),
    st.just(length))))


@SETTINGS
@given(blocks_strategy)
def test_that_fast_sync_status_round_trips_for_any_blocks(blocks) -> None:
    ids, errors, datas, length = blocks
    frame = encode_fast_sync_status(list(zip(ids, errors, datas)))
    assert _SDK.updateCRC(0, list(frame), len(frame) - 2) == frame[-2] | (frame[-1] << 8)
    assert decode_fast_sync_status(frame, length, ids) == {i: (e, d) for i, e, d in zip(ids, errors, datas)}


class _Wire:
    """A port stub: records what the host writes, answers every read with ``reply``."""

    timeout: float | None = None

    def __init__(self) -> None:
        self.written: list[bytes] = []
        self.reply = b""

    def write(self, data: bytes) -> int:
        self.written.append(bytes(data))
        return len(data)

    def read(self, size: int = 1) -> bytes:
        return self.reply

    def reset_input_buffer(self) -> None:
        pass


feedback_rows = st.lists(st.tuples(st.integers(-2**31, 2**31 - 1), st.integers(-2**31, 2**31 - 1),
                                   st.integers(-2**15, 2**15 - 1), st.integers(0, 255), st.integers(0, 255),
                                   st.integers(0, 2**16 - 1), st.sampled_from([0, 0, 0x80, 0x07])),
                         min_size=20, max_size=20)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(feedback_rows)
def test_that_the_numpy_feedback_decoder_matches_the_byte_codec(rows) -> None:
    smap = _map(20, 4_000_000)
    wire = _Wire()
    group = ServoGroup(DynamixelBus(wire, baud_rate=4_000_000, clock=FakeClock()), smap, fast_read=True)
    wire.reply = encode_fast_sync_status([(sid, err, struct.pack("<iihBBH", p, v, c, h, t, u))
                                          for sid, (p, v, c, h, t, u, err) in zip(smap.ids, rows)])
    fb = group.read_feedback()
    ok = np.array([(r[6] & 0x7F) == 0 for r in rows])
    np.testing.assert_array_equal(fb.valid, ok)
    np.testing.assert_array_equal(fb.error_byte, [r[6] for r in rows])
    np.testing.assert_allclose(fb.position_rad[ok], smap.to_radians(np.array([r[0] for r in rows]))[ok])
    np.testing.assert_allclose(fb.velocity_rad_s[ok], smap.velocity_to_rad_s(np.array([r[1] for r in rows]))[ok])
    np.testing.assert_array_equal(fb.hardware_error[ok], np.array([r[3] for r in rows])[ok])
    np.testing.assert_allclose(fb.voltage_v[ok], np.array([r[5] for r in rows])[ok] * 0.1)
    assert np.isnan(fb.position_rad[~ok]).all()


@SETTINGS
@given(st.lists(st.floats(-1.5, 1.5), min_size=20, max_size=20))
def test_that_the_precomputed_goal_frame_equals_the_generic_sync_write(q: list[float]) -> None:
    smap = _map(20, 1_000_000)
    wire = _Wire()
    group = ServoGroup(DynamixelBus(wire, baud_rate=1_000_000, clock=FakeClock()), smap)
    ticks = group.write_goals(np.array(q))
    expected = encode_packet(BROADCAST_ID, Instruction.SYNC_WRITE, sync_write_params(
        116, 4, {sid: struct.pack("<i", int(t)) for sid, t in zip(smap.ids, ticks)}))
    assert wire.written == [expected]


def _map(n: int, baud: int) -> ServoMap:
    servos = tuple(ServoSpec(i, f"j{i}", "XM430-W350", min=-1.5, max=1.5) for i in range(1, n + 1))
    return ServoMap("bench", BusSpec(baud, 0.0), servos)
