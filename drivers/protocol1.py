"""Dynamixel Protocol 1.0 packets: checksum, encode/decode, the status error bits, parameter layouts.

Pure functions on ``bytes``; used by the host driver (:mod:`drivers.bus1`) and by the emulator
(:mod:`drivers.mockbus.emulator1`) alike.

Frame layout (ROBOTIS e-manual, "Protocol 1.0",
https://emanual.robotis.com/docs/en/dxl/protocol1/):
``FF FF | ID | LEN | INST | PARAMS... | CHECKSUM`` where LEN = number of parameters + 2 and
CHECKSUM = ~(ID + LEN + INST + PARAMS) & 0xFF. A status packet has the same frame with the error
byte where an instruction packet has INST; its seven bits are alarms (input voltage, angle
limit, overheating, range, checksum, overload, instruction). Unlike Protocol 2.0 there is no
byte stuffing and no way to tell an instruction frame from a status frame by its bytes: the
direction is known from who reads (the host reads statuses, a servo instructions).

To reuse the 2.0 host and emulator machinery, a decoded status is a
:class:`drivers.protocol.Packet` with instruction ``Instruction.STATUS`` (0x55) and the error
byte as its first parameter, exactly as a 2.0 status decodes.

Group instructions: SYNC_WRITE (0x83: start address, data length, then ID + data per servo, no
reply) on every model; BULK_READ (0x92: a 0x00 byte, then LEN ID ADDR per servo) on the MX series
only: each servo sends its status after the status of the servo listed before it, so one silent
servo silences every servo after it (the host reads the rest one by one).
"""

from __future__ import annotations

import enum
from collections.abc import Iterable, Mapping

from drivers.errors import ProtocolError
from drivers.protocol import FrameReader, Instruction, Packet, _sync_write_blocks, wire_time_s  # wire_time_s re-exported

__all__ = [
    "HEADER1",
    "BROADCAST_ID",
    "MAX_ID",
    "Instruction1",
    "ErrorBits1",
    "checksum",
    "encode_instruction1",
    "encode_status1",
    "decode_instruction1",
    "decode_status1",
    "PacketReader1",
    "read_params1",
    "write_params1",
    "sync_write_params1",
    "bulk_read_params1",
    "parse_bulk_read_params1",
    "instruction_length1",
    "status_length1",
    "describe_error1",
    "wire_time_s",
]

HEADER1 = b"\xff\xff"
BROADCAST_ID = 0xFE
MAX_ID = 0xFD  # highest servo ID (253)
_MAX_LENGTH = 0xFF


class Instruction1(enum.IntEnum):
    """Instruction codes of Protocol 1.0 (e-manual Protocol 1.0, "Instruction Packet")."""

    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    RESET = 0x06  # factory reset: ID 1 and the default baud rate. The driver never sends it on its own.
    SYNC_WRITE = 0x83
    BULK_READ = 0x92  # MX series only


class ErrorBits1:
    """The seven alarm bits of a Protocol 1.0 status packet's error byte (bit 7 is always 0).

    Alarm LED and Alarm Shutdown (addresses 17 and 18) use the same bits.
    """

    INPUT_VOLTAGE = 0x01
    ANGLE_LIMIT = 0x02
    OVERHEATING = 0x04
    RANGE = 0x08
    CHECKSUM = 0x10
    OVERLOAD = 0x20
    INSTRUCTION = 0x40

    NAMES = {
        0x01: "input voltage",
        0x02: "angle limit",
        0x04: "overheating",
        0x08: "range",
        0x10: "checksum",
        0x20: "overload",
        0x40: "instruction",
    }
    # the bits that describe the servo's hardware (the rest refuse one instruction)
    HARDWARE = INPUT_VOLTAGE | OVERHEATING | OVERLOAD
    # the bits that mean "this instruction was refused"
    REFUSED = ANGLE_LIMIT | RANGE | CHECKSUM | INSTRUCTION

    @classmethod
    def describe(cls, bits: int) -> str:
        """E.g. ``"overheating, overload"``; ``"none"`` for 0."""
        names = [name for bit, name in cls.NAMES.items() if bits & bit]
        return ", ".join(names) or "none"


def describe_error1(error: int) -> str:
    """Human text for a status error byte, e.g. ``"range error, overload alarm"``."""
    refused = [f"{ErrorBits1.NAMES[b]} error" for b in ErrorBits1.NAMES if error & b & ErrorBits1.REFUSED]
    alarms = [f"{ErrorBits1.NAMES[b]} alarm" for b in ErrorBits1.NAMES if error & b & ErrorBits1.HARDWARE]
    return ", ".join(refused + alarms) or "ok"


def checksum(body: bytes | bytearray | memoryview) -> int:
    """Protocol 1.0 checksum of ``body`` (ID, LEN, INST or error, parameters): ~sum & 0xFF."""
    return (~sum(body)) & 0xFF


def _frame(servo_id: int, code: int, params: bytes) -> bytes:
    if not 0 <= servo_id <= 0xFE:
        raise ProtocolError(f"servo id {servo_id} outside 0..254")
    length = len(params) + 2
    if length > _MAX_LENGTH:
        raise ProtocolError(f"packet too long ({length} > {_MAX_LENGTH} in the length byte)")
    body = bytes((servo_id, length, code & 0xFF)) + bytes(params)
    return HEADER1 + body + bytes((checksum(body),))


def encode_instruction1(servo_id: int, instruction: int, params: bytes = b"") -> bytes:
    """Build a complete instruction frame."""
    return _frame(servo_id, instruction, params)


def encode_status1(servo_id: int, error: int, data: bytes = b"") -> bytes:
    """Build a complete status frame (``error``: the seven alarm bits)."""
    return _frame(servo_id, error & 0x7F, data)


def _check_frame(frame: bytes) -> None:
    if len(frame) < 6:
        raise ProtocolError(f"frame too short ({len(frame)} bytes, need at least 6)")
    if frame[:2] != HEADER1:
        raise ProtocolError(f"bad header {frame[:2].hex(' ')}")
    if frame[3] < 2 or len(frame) != 4 + frame[3]:
        raise ProtocolError(f"length field {frame[3]} does not match frame of {len(frame)} bytes")
    if checksum(frame[2:-1]) != frame[-1]:
        raise ProtocolError("checksum mismatch")


def decode_instruction1(frame: bytes) -> Packet:
    """Decode one instruction frame (what a servo reads); raise :class:`ProtocolError`."""
    _check_frame(frame)
    return Packet(frame[2], frame[4], bytes(frame[5:-1]))


def decode_status1(frame: bytes) -> Packet:
    """Decode one status frame (what the host reads) as a status :class:`Packet`: instruction
    ``Instruction.STATUS`` and the error byte first, as a 2.0 status decodes."""
    _check_frame(frame)
    return Packet(frame[2], Instruction.STATUS, bytes(frame[4:-1]))


class PacketReader1(FrameReader):
    """Incremental frame finder over a Protocol 1.0 byte stream.

    Garbage before a header is skipped; a frame with a bad checksum is dropped and counted in
    ``crc_errors`` (the 2.0 reader's name), and the search resumes one byte later, as a servo
    resynchronises.
    """

    _HEADER = HEADER1
    _PREFIX = 4  # FF FF ID LEN
    _MIN_LENGTH = 2  # INST (or error) + CHECKSUM

    def __init__(self, *, max_length: int = _MAX_LENGTH) -> None:
        super().__init__(max_length=max_length)

    def _length(self, buf: bytearray) -> int:
        if buf[2] == 0xFF:  # FF FF FF: the header starts one byte later
            return -1
        return buf[3]

    def _intact(self, frame: bytes) -> bool:
        return checksum(frame[2:-1]) == frame[-1]


# ---- parameter layouts (little endian, one-byte addresses) -------------------------------


def _address(address: int) -> int:
    if not 0 <= address <= 0xFF:
        raise ProtocolError(f"address {address} outside 0..255 (Protocol 1.0 addresses are one byte)")
    return address


def read_params1(address: int, length: int) -> bytes:
    """READ parameters: start address, data length (one byte each)."""
    if not 1 <= length <= 0xFF:
        raise ProtocolError(f"read length {length} outside 1..255")
    return bytes((_address(address), length))


def write_params1(address: int, data: bytes) -> bytes:
    """WRITE / REG_WRITE parameters: start address, data."""
    return bytes((_address(address),)) + bytes(data)


def sync_write_params1(address: int, length: int, data_by_id: Mapping[int, bytes]) -> bytes:
    """SYNC_WRITE parameters; every data block must be ``length`` bytes."""
    return bytes((_address(address), length)) + _sync_write_blocks(length, data_by_id)


def bulk_read_params1(items: Iterable[tuple[int, int, int]]) -> bytes:
    """BULK_READ parameters from ``(id, address, length)`` triples: 0x00, then LEN ID ADDR each."""
    out = bytearray((0x00,))
    for servo_id, address, length in items:
        out += bytes((length, servo_id, _address(address)))
    return bytes(out)


def parse_bulk_read_params1(params: bytes) -> list[tuple[int, int, int]]:
    """Inverse of :func:`bulk_read_params1`: ``(id, address, length)`` triples.

    Raises:
        ProtocolError: the parameters are not 0x00 followed by whole triples.
    """
    if not params or params[0] != 0x00 or (len(params) - 1) % 3:
        raise ProtocolError(f"bulk read parameters of {len(params)} bytes are not 0x00 + LEN ID ADDR triples")
    return [(params[k + 1], params[k + 2], params[k]) for k in range(1, len(params), 3)]


def instruction_length1(n_params: int) -> int:
    """Bytes on the wire of an instruction packet with ``n_params`` parameters."""
    return 6 + n_params


def status_length1(n_data: int) -> int:
    """Bytes on the wire of a status packet carrying ``n_data`` data bytes."""
    return 6 + n_data
