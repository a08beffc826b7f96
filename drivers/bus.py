"""``DynamixelBus``: Protocol 2.0 transactions over a serial port, errors surfaced.

The codec is :mod:`drivers.protocol` (shared with the emulator); the port is anything with the
pyserial interface (``write``, ``read``, ``reset_input_buffer``, ``timeout``). We use our own
codec instead of dynamixel-sdk's group classes because those drop each servo's status error
byte (the hardware alert bit), discard a whole group read when one servo is silent and size
their timeouts for a 16 ms latency timer; dynamixel-sdk itself is used by the compatibility
tests against the emulator.

Every group read returns a :class:`GroupRead` with per-servo data, per-servo error bytes and the
IDs that did not answer, so that one silent servo never costs the others' data.
"""

from __future__ import annotations

import logging
import struct
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol

from drivers.clock import Clock, MonotonicClock
from drivers.control_table import EEPROM_END, Register
from drivers.errors import CommunicationError, ProtocolError, ServoStatusError, ServoTimeout
from drivers.protocol import (
    BROADCAST_ID,
    HEADER,
    FrameReader,
    Instruction,
    PacketReader,
    bulk_read_params,
    bulk_write_params,
    crc16,
    decode_fast_sync_status,
    decode_packet,
    describe_error,
    encode_packet,
    read_params,
    status_length,
    sync_read_params,
    sync_write_params,
    wire_time_s,
    write_params,
)

__all__ = ["Transport", "PingResult", "GroupRead", "BusStats", "DynamixelBus"]

_log = logging.getLogger(__name__)
_NOT_RETRIED = (Instruction.REBOOT, Instruction.FACTORY_RESET)


class Transport(Protocol):
    """The subset of pyserial's ``SerialBase`` the bus needs."""

    timeout: float | None

    def write(self, data: bytes) -> int | None: ...

    def read(self, size: int = 1) -> bytes: ...

    def reset_input_buffer(self) -> None: ...


@dataclass(frozen=True)
class PingResult:
    """A ping answer: model number, firmware version, status error byte."""

    servo_id: int
    model_number: int
    firmware_version: int
    error: int = 0


@dataclass(frozen=True)
class GroupRead:
    """Result of a (fast) sync or bulk read.

    Attributes:
        data: ``{id: bytes}`` of every servo that answered with valid data.
        errors: ``{id: status error byte}`` of every servo that answered (bit 7 = alert).
        missing: IDs without a valid answer, in request order.
        fast: the reply came from one Fast Sync Read frame.
    """

    data: Mapping[int, bytes]
    errors: Mapping[int, int]
    missing: tuple[int, ...]
    fast: bool = False

    @property
    def complete(self) -> bool:
        return not self.missing


@dataclass
class BusStats:
    """Counters of one bus (mutable, owned by the bus)."""

    packets_sent: int = 0
    bytes_sent: int = 0
    bytes_received: int = 0
    timeouts: int = 0
    corrupt_replies: int = 0
    fast_read_failures: int = 0
    stale_replies: int = 0
    by_id_timeouts: dict[int, int] = field(default_factory=dict)


class DynamixelBus:
    """Protocol 2.0 master on one serial port.

    Args:
        port: an open pyserial-like port.
        baud_rate: bus speed [bit/s] (for reply timeouts).
        clock: time source shared with the caller (and with the emulator in tests).
        rx_margin_s: slack added to every reply timeout [s] (USB latency, firmware jitter).
        return_delay_s: servo Return Delay Time [s] assumed for timeouts.
        retries: extra attempts of a single-servo instruction that got no reply (not for
            REBOOT, whose reply may be lost to the reboot itself). Group reads never retry:
            the servo group isolates silent servos instead.

    Use as a context manager to close the port on exit.

    The class attributes below name the codec; :class:`drivers.bus1.DynamixelBus1` sets its 1.0
    counterparts (the instruction codes used here, PING to ACTION and SYNC_WRITE, are the same
    on both protocols).
    """

    _reader_class: type[FrameReader] = PacketReader
    _min_status_bytes = status_length(0)  # [bytes] read on when a frame is cut off
    _encode = staticmethod(encode_packet)
    _read_params = staticmethod(read_params)
    _write_params = staticmethod(write_params)
    _sync_write_params = staticmethod(sync_write_params)
    _describe_error = staticmethod(describe_error)
    _refused_bits = 0x7F  # status error bits that mean the instruction was refused (the error number)
    _eeprom_end = EEPROM_END  # addresses below it need torque off to be written

    def __init__(self, port: Transport, *, baud_rate: int, clock: Clock | None = None,
                 rx_margin_s: float = 0.004, return_delay_s: float = 0.0005, retries: int = 1) -> None:
        self.port = port
        self.baud_rate = baud_rate
        self.clock: Clock = clock or MonotonicClock()
        self.rx_margin_s = rx_margin_s
        self.return_delay_s = return_delay_s
        self.retries = retries
        self.stats = BusStats()
        self._timeout: float | None = None
        self._last_tx_bytes = 0  # bytes of the last write() (replies queue behind them)
        self._tx_queue: list[bytes] = []  # deferred no-reply frames, sent with the next packet
        self._request_cache: dict[tuple[int, int, int, tuple[int, ...]], bytes] = {}
        # the input may hold stale bytes (a late, partial or unexpected reply): flush it before
        # the next instruction. A transaction that got exactly the bytes it expected leaves the
        # line clean, and the flush (one ioctl per cycle) is skipped.
        self._input_dirty = True

    def __enter__(self) -> "DynamixelBus":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        try:
            self.flush()
        except CommunicationError:
            pass
        close = getattr(self.port, "close", None)
        if close is not None:
            close()

    # ---- low level -----------------------------------------------------------------------
    def _reply_timeout(self, n_bytes: int, n_replies: int) -> float:
        # the replies follow everything the last write() put on the wire (deferred frames too)
        return (wire_time_s(n_bytes + self._last_tx_bytes, self.baud_rate) + n_replies * self.return_delay_s
                + self.rx_margin_s)

    def flush(self) -> None:
        """Send deferred frames now (normally they go out with the next instruction)."""
        if self._tx_queue:
            self._send(b"")

    def _send(self, frame: bytes) -> None:
        if self._tx_queue:  # deferred sync writes share this packet's write() call
            self._tx_queue.append(frame)
            frame = b"".join(self._tx_queue)
            self._tx_queue.clear()
        try:
            if self._input_dirty:
                self.port.reset_input_buffer()
                self._input_dirty = False
            self.port.write(frame)
        except (OSError, ValueError) as e:  # serial.SerialException is an OSError
            raise CommunicationError(f"write to port failed: {e}",
                                     hint="the adapter may have been unplugged") from e
        self.stats.packets_sent += 1
        self.stats.bytes_sent += len(frame)
        self._last_tx_bytes = len(frame)
        if _log.isEnabledFor(logging.DEBUG):
            _log.debug("tx %s", frame.hex(" "))

    def _receive(self, n_bytes: int, timeout_s: float) -> bytes:
        if self._timeout != timeout_s:
            self.port.timeout = timeout_s
            self._timeout = timeout_s
        try:
            data = self.port.read(n_bytes)
        except (OSError, ValueError) as e:
            raise CommunicationError(f"read from port failed: {e}") from e
        self.stats.bytes_received += len(data)
        if _log.isEnabledFor(logging.DEBUG):
            _log.debug("rx %s", data.hex(" "))
        return data

    def _collect_frames(self, n_frames: int, expected_bytes: int,
                        accept: Callable[[bytes], bool] | None = None, *, first: bytes | None = None) -> list[bytes]:
        """Read until ``n_frames`` accepted frames or the timeout; corrupt frames are skipped.

        Frames ``accept`` rejects (a late reply to an earlier instruction) are dropped and
        counted in ``stats.stale_replies``; reading goes on for the frames we want.
        ``first``: bytes already read for this reply (the first read is then not repeated).
        """
        reader = self._reader_class()
        frames: list[bytes] = []
        timeout = self._reply_timeout(expected_bytes, n_frames)
        want = expected_bytes
        for attempt in range(6):  # one read normally; more after stuffing, stale or split replies
            if attempt == 0 and first is not None:
                chunk = first
            else:
                chunk = self._receive(max(want, 1), timeout)
            if not chunk:
                break
            reader.feed(chunk)
            want -= len(chunk)
            while (frame := reader.next_frame()) is not None:
                if accept is None or accept(frame):
                    frames.append(frame)
                else:
                    self.stats.stale_replies += 1
                    want += len(frame)
            if len(frames) >= n_frames:
                break
            if want <= 0:
                want = max(1, reader.pending and self._min_status_bytes)
                timeout = self.rx_margin_s
        self.stats.corrupt_replies += reader.crc_errors
        if len(frames) < n_frames or reader.pending or reader.crc_errors or reader.skipped_bytes:
            self._input_dirty = True
        return frames

    def transact(self, servo_id: int, instruction: int, params: bytes = b"",
                 *, reply_data_len: int = 0) -> tuple[int, bytes]:
        """Send one instruction to ``servo_id`` and wait for its status.

        Returns:
            (status error byte, data).

        Raises:
            ServoTimeout: no valid status arrived.
        """
        frame = encode_packet(servo_id, instruction, params)
        def accept(f: bytes) -> bool:
            # a late reply to an earlier instruction of the same servo is told apart by its
            # data size; an error status may come without data
            if f[4] != servo_id or f[7] != Instruction.STATUS:
                return False
            p = decode_packet(f)
            return len(p.data) == reply_data_len or bool(p.error & 0x7F)

        reply = self._request(frame, servo_id, status_length(reply_data_len), accept,
                              retry=instruction not in _NOT_RETRIED)
        p = decode_packet(reply)
        return p.error, p.data

    def _request(self, frame: bytes, servo_id: int, reply_bytes: int, accept: Callable[[bytes], bool], *,
                 retry: bool = True) -> bytes:
        """Send ``frame`` and return the first status frame ``accept`` takes (``reply_bytes`` long
        when clean), with ``retries`` more attempts unless ``retry`` is False.

        Raises:
            ServoTimeout: no such frame arrived.
        """
        for attempt in range(1 + self.retries):
            self._send(frame)
            frames = self._collect_frames(1, reply_bytes, accept)
            if frames:
                return frames[0]
            self._note_timeout((servo_id,))
            if not retry:
                break
            _log.debug("servo %d: no reply (attempt %d)", servo_id, attempt + 1)
        raise ServoTimeout([servo_id], frame)

    def _note_timeout(self, ids: Iterable[int]) -> None:
        self.stats.timeouts += 1
        for i in ids:
            self.stats.by_id_timeouts[i] = self.stats.by_id_timeouts.get(i, 0) + 1

    # ---- single-servo instructions -------------------------------------------------------
    def ping(self, servo_id: int) -> PingResult | None:
        """Ping one servo; ``None`` if it does not answer."""
        try:
            error, data = self.transact(servo_id, Instruction.PING, reply_data_len=3)
        except ServoTimeout:
            return None
        if len(data) != 3:
            self.stats.corrupt_replies += 1
            return None
        model, fw = struct.unpack("<HB", data)
        return PingResult(servo_id, model, fw, error)

    def scan(self, ids: Iterable[int]) -> dict[int, PingResult]:
        """Ping each of ``ids``; return the answers by ID (absent IDs are left out)."""
        found = {}
        for i in ids:
            r = self.ping(i)
            if r is not None:
                found[i] = r
        return found

    def read(self, servo_id: int, address: int, length: int) -> tuple[int, bytes]:
        """READ ``length`` bytes at ``address``; returns (error byte, data)."""
        error, data = self.transact(servo_id, Instruction.READ, self._read_params(address, length),
                                    reply_data_len=length)
        if error & self._refused_bits:
            raise ServoStatusError(servo_id, error, f"read of {length} bytes at {address} refused: "
                                   + self._describe_error(error))
        if len(data) != length:
            raise CommunicationError(f"servo {servo_id}: read returned {len(data)} bytes, not {length}")
        return error, data

    def write(self, servo_id: int, address: int, data: bytes) -> int:
        """WRITE ``data`` at ``address`` and wait for the status; returns the error byte.

        Raises:
            ServoStatusError: the servo refused the write (2.0: error number != 0; 1.0: range,
                angle limit, instruction error).
        """
        error, _ = self.transact(servo_id, Instruction.WRITE, self._write_params(address, data))
        if error & self._refused_bits:
            eeprom_end = self._eeprom_end
            raise ServoStatusError(servo_id, error, f"write of {len(data)} bytes at {address} refused: "
                                   + self._describe_error(error),
                                   hint=f"EEPROM (address < {eeprom_end}) needs torque off" if address < eeprom_end else "")
        return error

    def read_value(self, servo_id: int, register: Register) -> int:
        """Integer value of ``register`` on ``servo_id``."""
        _, data = self.read(servo_id, register.address, register.size)
        return register.decode(data)

    def write_value(self, servo_id: int, register: Register, value: int) -> int:
        """Write integer ``value`` to ``register``; returns the status error byte."""
        return self.write(servo_id, register.address, register.encode(value))

    def reboot(self, servo_id: int) -> int:
        """REBOOT ``servo_id``; returns the status error byte sent before the reboot."""
        error, _ = self.transact(servo_id, Instruction.REBOOT)
        return error

    def reg_write(self, servo_id: int, address: int, data: bytes) -> int:
        error, _ = self.transact(servo_id, Instruction.REG_WRITE, write_params(address, data))
        return error

    def action(self, servo_id: int = BROADCAST_ID) -> None:
        """ACTION: apply registered writes (broadcast by default, no reply)."""
        self._send(self._encode(servo_id, Instruction.ACTION))

    # ---- group instructions --------------------------------------------------------------
    def sync_write(self, address: int, length: int, data_by_id: Mapping[int, bytes], *,
                   defer: bool = False) -> None:
        """SYNC_WRITE the same register span on several servos (no reply).

        With ``defer`` the frame is queued and goes out in the same ``write()`` as the next
        instruction (one USB transfer for goal write + feedback read), or on :meth:`flush`.
        """
        if data_by_id:
            self.sync_write_params(self._sync_write_params(address, length, data_by_id), defer=defer)

    def sync_write_params(self, params: bytes, *, defer: bool = False) -> None:
        """SYNC_WRITE with prebuilt parameters (address, length, then id + data per servo)."""
        frame = self._encode(BROADCAST_ID, Instruction.SYNC_WRITE, params)
        if defer:
            self._tx_queue.append(frame)
        else:
            self._send(frame)

    def fast_sync_read_raw(self, address: int, length: int, ids: tuple[int, ...]) -> bytes | None:
        """FAST_SYNC_READ returning the validated raw reply frame, or ``None`` on any failure.

        The request frame is built once per (address, length, ids). The reply is checked for
        size, header and CRC only; the caller splits the ``8 + k * (4 + length)`` blocks
        (``ERR ID DATA CRC2`` each) itself, e.g. with one numpy structured view.
        Equivalent to :meth:`send_fast_sync_read` then :meth:`receive_fast_sync_read`.
        """
        self.send_fast_sync_read(address, length, ids)
        return self.receive_fast_sync_read(length, ids)

    def send_fast_sync_read(self, address: int, length: int, ids: tuple[int, ...]) -> None:
        """Send a FAST_SYNC_READ request (with any deferred frames) without waiting for the reply.

        The reply must be collected with :meth:`receive_fast_sync_read` before the next
        instruction (the bus is half duplex). Splitting the two lets a caller prepare the next
        cycle while the reply is on the wire.
        """
        key = (Instruction.FAST_SYNC_READ, address, length, ids)
        frame = self._request_cache.get(key)
        if frame is None:
            frame = encode_packet(BROADCAST_ID, Instruction.FAST_SYNC_READ, sync_read_params(address, length, ids))
            if len(self._request_cache) > 64:
                self._request_cache.clear()
            self._request_cache[key] = frame
        self._send(frame)

    def receive_fast_sync_read(self, length: int, ids: tuple[int, ...]) -> bytes | None:
        """The validated raw reply to the last :meth:`send_fast_sync_read` of ``ids``, or ``None``."""
        expected = 8 + len(ids) * (4 + length)
        raw = self._receive(expected, self._reply_timeout(expected, len(ids)))
        if (len(raw) != expected or raw[:4] != HEADER or raw[4] != BROADCAST_ID
                or raw[7] != Instruction.STATUS or crc16(raw[:-2]) != (raw[-2] | (raw[-1] << 8))):
            self._input_dirty = True
            self.stats.fast_read_failures += 1
            if len(raw) < expected:
                self._note_timeout(ids)
            else:
                self.stats.corrupt_replies += 1
            _log.debug("fast sync read failed (%d of %d bytes)", len(raw), expected)
            return None
        return raw

    def bulk_write(self, items: Sequence[tuple[int, int, bytes]]) -> None:
        """BULK_WRITE ``(id, address, data)`` items (no reply)."""
        if items:
            self._send(encode_packet(BROADCAST_ID, Instruction.BULK_WRITE, bulk_write_params(items)))

    def sync_read(self, address: int, length: int, ids: Sequence[int], *, fast: bool = False) -> GroupRead:
        """(Fast) SYNC_READ ``length`` bytes at ``address`` from ``ids``.

        A failed Fast Sync Read (one silent servo breaks the shared frame) returns every ID as
        missing with ``fast=True``; the caller falls back to a plain read to isolate the culprit.
        """
        ids = list(ids)
        if not ids:
            return GroupRead({}, {}, ())
        inst = Instruction.FAST_SYNC_READ if fast else Instruction.SYNC_READ
        frame = encode_packet(BROADCAST_ID, inst, sync_read_params(address, length, ids))
        self._send(frame)
        if fast:
            return self._fast_reply(ids, [length] * len(ids), frame)
        return self._plain_replies(ids, [length] * len(ids))

    def bulk_read(self, items: Sequence[tuple[int, int, int]], *, fast: bool = False) -> GroupRead:
        """(Fast) BULK_READ ``(id, address, length)`` items."""
        if not items:
            return GroupRead({}, {}, ())
        inst = Instruction.FAST_BULK_READ if fast else Instruction.BULK_READ
        frame = encode_packet(BROADCAST_ID, inst, bulk_read_params(items))
        self._send(frame)
        ids = [i for i, _, _ in items]
        lengths = [n for _, _, n in items]
        if fast:
            return self._fast_reply(ids, lengths, frame)
        return self._plain_replies(ids, lengths)

    def _plain_replies(self, ids: list[int], lengths: list[int]) -> GroupRead:
        expected = sum(status_length(n) for n in lengths)
        want = dict(zip(ids, lengths))
        frames = self._collect_frames(len(ids), expected,
                                      lambda f: f[4] in want and f[7] == Instruction.STATUS)
        data: dict[int, bytes] = {}
        errors: dict[int, int] = {}
        for f in frames:
            p = decode_packet(f)
            if p.is_status and p.servo_id in want and p.servo_id not in data:
                errors[p.servo_id] = p.error
                if len(p.data) == want[p.servo_id] and not (p.error & 0x7F):
                    data[p.servo_id] = p.data
        missing = tuple(i for i in ids if i not in data)
        if missing:
            self._note_timeout(missing)
        return GroupRead(data, errors, missing)

    def _fast_reply(self, ids: list[int], lengths: list[int], request: bytes) -> GroupRead:
        expected = 8 + sum(4 + n for n in lengths)
        raw = self._receive(expected, self._reply_timeout(expected, len(ids)))
        if len(raw) != expected:
            self._input_dirty = True
        try:
            if len(set(lengths)) == 1:
                blocks = decode_fast_sync_status(raw, lengths[0], ids)
            else:
                blocks = _decode_fast_bulk(raw, ids, lengths)
        except ProtocolError as e:
            _log.debug("fast read failed: %s", e)
            self.stats.fast_read_failures += 1
            if len(raw) < expected:
                self._note_timeout(ids)
            else:
                self.stats.corrupt_replies += 1
            return GroupRead({}, {}, tuple(ids), fast=True)
        data = {i: d for i, (e, d) in blocks.items() if not (e & 0x7F)}
        errors = {i: e for i, (e, _) in blocks.items()}
        missing = tuple(i for i in ids if i not in data)
        return GroupRead(data, errors, missing, fast=True)


def _decode_fast_bulk(frame: bytes, ids: Sequence[int], lengths: Sequence[int]) -> dict[int, tuple[int, bytes]]:
    expected = 8 + sum(4 + n for n in lengths)
    if len(frame) != expected or frame[:4] != HEADER or crc16(frame[:-2]) != (frame[-2] | (frame[-1] << 8)):
        raise ProtocolError("bad fast bulk read reply")
    out = {}
    pos = 8
    for i, n in zip(ids, lengths):
        if frame[pos + 1] != i:
            raise ProtocolError(f"fast bulk read block for id {frame[pos + 1]} where {i} was expected")
        out[i] = (frame[pos], bytes(frame[pos + 2 : pos + 2 + n]))
        pos += 4 + n
    return out
