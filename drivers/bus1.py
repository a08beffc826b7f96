"""``DynamixelBus1``: Protocol 1.0 transactions over a serial port, errors surfaced as on 2.0.

The same master as :class:`drivers.bus.DynamixelBus` (port handling, deferred frames, stale-reply
filtering, statistics, typed errors and timeouts), speaking the 1.0 codec of
:mod:`drivers.protocol1`:

- PING answers with no data; :meth:`DynamixelBus1.ping` then READs Model Number and Firmware
  Version (addresses 0..2) so that a :class:`~drivers.bus.PingResult` means the same on both buses.
- READ / WRITE / REG_WRITE / ACTION; RESET (factory reset: ID 1, default baud) only when asked
  by name (:meth:`DynamixelBus1.factory_reset`); there is no REBOOT on 1.0.
- SYNC_WRITE (no reply) on every model; BULK_READ on the MX series: the servos answer in list
  order, each after the one before it, so a silent servo silences the rest of the list. A
  partial bulk read returns what arrived, and the missing IDs are then READ one by one
  (:meth:`DynamixelBus1.bulk_read` with ``isolate=True``), so one silent servo never costs the
  others' data. SYNC_READ does not exist on 1.0: :meth:`DynamixelBus1.sync_read` is a READ per
  servo with the same :class:`~drivers.bus.GroupRead` result.

Error byte: the refused-instruction bits (range, angle limit, checksum, instruction) make a
READ or WRITE raise :class:`~drivers.errors.ServoStatusError`; the alarm bits (input voltage,
overheating, overload) come with valid data and are reported in ``GroupRead.errors`` (the group
turns them into hardware error bits).
"""

from __future__ import annotations

import logging
import struct
from collections.abc import Iterable, Sequence

from drivers.bus import DynamixelBus, GroupRead, PingResult, Transport
from drivers.clock import Clock
from drivers.control_table1 import EEPROM_END_1
from drivers.errors import CommunicationError, ProtocolError, ServoStatusError, ServoTimeout
from drivers.protocol1 import (
    BROADCAST_ID,
    ErrorBits1,
    Instruction1,
    PacketReader1,
    bulk_read_params1,
    decode_status1,
    describe_error1,
    encode_instruction1,
    read_params1,
    status_length1,
    sync_write_params1,
    write_params1,
)

__all__ = ["DynamixelBus1"]

_log = logging.getLogger(__name__)
_PING_DATA = (0, 3)  # (address, length): Model Number (2) and Firmware Version (1)


class DynamixelBus1(DynamixelBus):
    """Protocol 1.0 master on one serial port (arguments as :class:`~drivers.bus.DynamixelBus`).

    READ, WRITE, ACTION and SYNC_WRITE are the 2.0 bus's, with the 1.0 codec below.
    """

    protocol = 1.0
    _reader_class = PacketReader1
    _min_status_bytes = status_length1(0)
    _encode = staticmethod(encode_instruction1)
    _read_params = staticmethod(read_params1)
    _write_params = staticmethod(write_params1)
    _sync_write_params = staticmethod(sync_write_params1)
    _describe_error = staticmethod(describe_error1)
    _refused_bits = ErrorBits1.REFUSED
    _eeprom_end = EEPROM_END_1

    def __init__(self, port: Transport, *, baud_rate: int, clock: Clock | None = None,
                 rx_margin_s: float = 0.004, return_delay_s: float = 0.0005, retries: int = 1) -> None:
        super().__init__(port, baud_rate=baud_rate, clock=clock, rx_margin_s=rx_margin_s,
                         return_delay_s=return_delay_s, retries=retries)
        self._bulk_cache: dict[tuple[tuple[int, int, int], ...], bytes] = {}  # request frames

    # ---- low level -----------------------------------------------------------------------
    def transact(self, servo_id: int, instruction: int, params: bytes = b"",
                 *, reply_data_len: int = 0) -> tuple[int, bytes]:
        """Send one 1.0 instruction to ``servo_id`` and wait for its status.

        Returns:
            (status error byte, data).

        Raises:
            ServoTimeout: no valid status arrived (after ``retries`` more attempts).
        """
        frame = encode_instruction1(servo_id, instruction, params)

        def accept(f: bytes) -> bool:
            # a late reply to an earlier instruction is told apart by its data size; a refusal
            # may come without data
            return f[2] == servo_id and (f[3] - 2 == reply_data_len or bool(f[4] & ErrorBits1.REFUSED))

        p = decode_status1(self._request(frame, servo_id, status_length1(reply_data_len), accept))
        return p.error, p.data

    # ---- single-servo instructions -------------------------------------------------------
    def ping(self, servo_id: int) -> PingResult | None:
        """PING one servo, then read its model number and firmware; ``None`` if it is silent."""
        try:
            error, _ = self.transact(servo_id, Instruction1.PING)
            error2, data = self.transact(servo_id, Instruction1.READ, read_params1(*_PING_DATA),
                                         reply_data_len=_PING_DATA[1])
        except ServoTimeout:
            return None
        if len(data) != 3 or error2 & ErrorBits1.REFUSED:
            self.stats.corrupt_replies += 1
            return None
        model, fw = struct.unpack("<HB", data)
        return PingResult(servo_id, model, fw, (error | error2) & ErrorBits1.HARDWARE)

    def reboot(self, servo_id: int) -> int:
        """Protocol 1.0 has no REBOOT instruction (RESET would restore the factory ID and baud)."""
        raise CommunicationError(f"servo {servo_id}: Protocol 1.0 has no reboot instruction",
                                 hint="power-cycle the servo, or rewrite Torque Limit to clear an alarm shutdown")

    def factory_reset(self, servo_id: int) -> int:
        """RESET ``servo_id`` to its factory settings (ID 1, default baud rate); returns the error byte."""
        error, _ = self.transact(servo_id, Instruction1.RESET)
        return error

    def reg_write(self, servo_id: int, address: int, data: bytes) -> int:
        error, _ = self.transact(servo_id, Instruction1.REG_WRITE, write_params1(address, data))
        if error & ErrorBits1.REFUSED:
            raise ServoStatusError(servo_id, error, "registered write refused: " + describe_error1(error))
        return error

    # ---- group instructions (SYNC_WRITE as on 2.0, with the 1.0 codec) -------------------
    def bulk_write(self, items: Sequence[tuple[int, int, bytes]]) -> None:
        raise ProtocolError("BULK_WRITE is a Protocol 2.0 instruction", hint="use sync_write or write")

    def fast_sync_read_raw(self, address: int, length: int, ids: tuple[int, ...]) -> bytes | None:
        return None  # no Fast Sync Read on 1.0

    def send_fast_sync_read(self, address: int, length: int, ids: tuple[int, ...]) -> None:
        raise ProtocolError("FAST_SYNC_READ is a Protocol 2.0 instruction")

    def receive_fast_sync_read(self, length: int, ids: tuple[int, ...]) -> bytes | None:
        return None

    def sync_read(self, address: int, length: int, ids: Sequence[int], *, fast: bool = False) -> GroupRead:
        """``length`` bytes at ``address`` from each of ``ids`` by one READ each (1.0 has no
        SYNC_READ); silent or refusing servos are ``missing``."""
        return self.read_each_servo([(i, address, length) for i in ids])

    def read_each_servo(self, items: Iterable[tuple[int, int, int]]) -> GroupRead:
        """One READ per ``(id, address, length)`` item, no retry; a :class:`GroupRead`."""
        data: dict[int, bytes] = {}
        errors: dict[int, int] = {}
        missing: list[int] = []
        retries, self.retries = self.retries, 0
        try:
            for sid, address, length in items:
                try:
                    error, d = self.transact(sid, Instruction1.READ, read_params1(address, length),
                                             reply_data_len=length)
                except ServoTimeout:
                    missing.append(sid)
                    continue
                errors[sid] = error
                if len(d) == length and not error & ErrorBits1.REFUSED:
                    data[sid] = d
                else:
                    missing.append(sid)
        finally:
            self.retries = retries
        return GroupRead(data, errors, tuple(missing))

    def bulk_read(self, items: Sequence[tuple[int, int, int]], *, fast: bool = False,
                  isolate: bool = True) -> GroupRead:
        """BULK_READ ``(id, address, length)`` items (MX series); the replies come in list order.

        With ``isolate`` the servos that did not answer (a silent servo silences every servo
        listed after it) are then READ one by one, so the result holds every answering servo.
        """
        if not items:
            return GroupRead({}, {}, ())
        key = tuple(items)
        frame = self._bulk_cache.get(key)
        if frame is None:
            frame = encode_instruction1(BROADCAST_ID, Instruction1.BULK_READ, bulk_read_params1(items))
            if len(self._bulk_cache) > 64:
                self._bulk_cache.clear()
            self._bulk_cache[key] = frame
        self._send(frame)
        want = {i: n for i, _, n in items}
        expected = sum(status_length1(n) for _, _, n in items)
        raw = self._receive(expected, self._reply_timeout(expected, len(items)))
        fast = _split_in_order(raw, items) if len(raw) == expected else None
        if fast is not None:  # the usual case: every status, in list order, checksums right
            return fast
        frames = self._collect_frames(len(items), expected,
                                       lambda f: f[2] in want and f[3] - 2 in (want[f[2]], 0), first=raw)
        data: dict[int, bytes] = {}
        errors: dict[int, int] = {}
        for f in frames:
            p = decode_status1(f)
            if p.servo_id in data:
                continue
            errors[p.servo_id] = p.error
            if len(p.data) == want[p.servo_id] and not p.error & ErrorBits1.REFUSED:
                data[p.servo_id] = p.data
        missing = [i for i, _, _ in items if i not in data]
        if missing:
            self._note_timeout(missing)
            if isolate:
                rest = self.read_each_servo([it for it in items if it[0] in missing])
                data.update(rest.data)
                errors.update(rest.errors)
                missing = list(rest.missing)
        return GroupRead(data, errors, tuple(missing))

    def _plain_replies(self, ids: list[int], lengths: list[int]) -> GroupRead:  # pragma: no cover
        raise ProtocolError("2.0 group replies on a 1.0 bus")


def _split_in_order(raw: bytes, items: Sequence[tuple[int, int, int]]) -> GroupRead | None:
    """``raw`` as the statuses of ``items`` back to back, in order, each checksum right and no
    refused-instruction bit; ``None`` otherwise (the caller parses it the slow way)."""
    data: dict[int, bytes] = {}
    errors: dict[int, int] = {}
    pos = 0
    for sid, _, n in items:
        end = pos + 6 + n
        if raw[pos] != 0xFF or raw[pos + 1] != 0xFF or raw[pos + 2] != sid or raw[pos + 3] != n + 2:
            return None
        if (~sum(raw[pos + 2 : end - 1])) & 0xFF != raw[end - 1]:
            return None
        error = raw[pos + 4]
        if error & ErrorBits1.REFUSED:
            return None
        errors[sid] = error
        data[sid] = raw[pos + 5 : end - 1]
        pos = end
    return GroupRead(data, errors, ())

