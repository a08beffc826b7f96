"""The emulated Protocol 1.0 bus: AX, RX and MX (1.0 firmware) servos, byte for byte.

:class:`MockBus1` is a :class:`~drivers.mockbus.MockBus` (the same clock, plant, physics twin,
faults, wire timing, packet log and listeners; the ``dxlsim://`` port and the pseudo-terminal
server take either) whose servos are :class:`~drivers.mockbus.emulated_servo1.EmulatedServo1`
and whose codec is :mod:`drivers.protocol1`. It answers PING, READ, WRITE, REG_WRITE, ACTION,
RESET, SYNC_WRITE and, on MX servos, BULK_READ.

BULK_READ as the firmware does it: each listed servo sends its status after it has heard the
status of the servo listed before it. A servo that is silent (unplugged, deaf, ``silent_ids``,
an AX that has no BULK_READ) or whose status is lost or corrupted on the wire (the fault
injector) leaves the next servo waiting: the rest of the list stays silent.

There is no OpenCR on a 1.0 bus (it speaks 2.0): ``imu`` is refused.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping

from drivers.clock import Clock, MonotonicClock
from drivers.control_table import control_table
from drivers.control_table1 import BAUD_INDEX_BY_RATE_1, BAUD_RATE_BY_INDEX_1
from drivers.errors import ProtocolError
from drivers.mockbus.emulated_servo1 import EmulatedServo1
from drivers.mockbus.emulator import _PLANT_PERIOD_S, MockBus, Reply
from drivers.mockbus.faults import FaultInjector
from drivers.mockbus.plant import KinematicPlant, Plant
from drivers.protocol import Packet
from drivers.protocol1 import (
    BROADCAST_ID,
    ErrorBits1,
    Instruction1,
    PacketReader1,
    decode_instruction1,
    encode_status1,
    parse_bulk_read_params1,
    wire_time_s,
)

__all__ = ["MockBus1"]

_log = logging.getLogger(__name__)
_SINGLE = (Instruction1.PING, Instruction1.READ, Instruction1.WRITE, Instruction1.REG_WRITE,
           Instruction1.ACTION, Instruction1.RESET)


class MockBus1(MockBus):
    """A byte-level Protocol 1.0 bus (arguments as :class:`~drivers.mockbus.MockBus`; ``servos``
    name 1.0 models, e.g. ``{11: "MX-28", 36: "AX-18A"}``; ``firmware_version`` None keeps each
    model's default)."""

    protocol = 1.0

    def __init__(self, servos: Mapping[int, str], *, baud_rate: int = 1_000_000,
                 clock: Clock | None = None, plant: Plant | None = None,
                 faults: FaultInjector | None = None, wire_timing: bool = False,
                 return_delay_units: int = 0, initial_position_ticks: Mapping[int, int] | None = None,
                 firmware_version: int | None = None, boot_time_s: float = 0.05,
                 plant_period_s: float = _PLANT_PERIOD_S, imu: object | None = None) -> None:
        if baud_rate not in BAUD_INDEX_BY_RATE_1:
            raise ValueError(f"baud_rate {baud_rate} is not a Protocol 1.0 rate {sorted(BAUD_INDEX_BY_RATE_1)}")
        if imu is not None:
            raise ValueError("the OpenCR (IMU) speaks Protocol 2.0; a 1.0 bus has none")
        self.baud_rate = baud_rate
        self.clock = clock or MonotonicClock()
        self.faults = faults or FaultInjector()
        self.wire_timing = wire_timing
        self.boot_time_s = boot_time_s
        self.plant_period_s = plant_period_s
        init = dict(initial_position_ticks or {})
        self.servos = {}  # type: ignore[assignment]  (EmulatedServo1 has EmulatedServo's bus interface)
        initial_rad = {}
        for sid, model in servos.items():
            table = control_table(model, 1.0)
            s = EmulatedServo1(sid, table, baud_index=BAUD_INDEX_BY_RATE_1[baud_rate],
                               return_delay_units=return_delay_units,
                               initial_position_ticks=init.get(sid, table.center_ticks),
                               firmware_version=firmware_version)
            self.servos[sid] = s  # type: ignore[assignment]
            initial_rad[sid] = s.position_rad
        self.plant = plant if plant is not None else KinematicPlant(initial_rad=initial_rad)
        self.imu = None
        self._reader = PacketReader1()  # type: ignore[assignment]
        self._last_s = self.clock.now()
        self._wire_free_s = self._last_s
        for s in self.servos.values():
            s.start_s = self._last_s
            s.watchdog_last_feed_s = self._last_s
        self.packets_received = 0
        self.log = []
        self._log_limit = 10000
        self.packet_listeners = []

    # ---- bytes in, replies out -----------------------------------------------------------
    def receive(self, data: bytes, now_s: float | None = None) -> list[Reply]:
        """Process bytes written by the host at ``now_s``; return the replies, in wire order."""
        now = self.clock.now() if now_s is None else now_s
        self.advance(now)
        self._reader.feed(data)
        replies: list[Reply] = []
        t_free = max(now, self._wire_free_s) if self.wire_timing else now
        while True:
            frame = self._reader.next_frame()
            if frame is None:
                break
            try:
                packet = decode_instruction1(frame)
            except ProtocolError:
                continue
            self.packets_received += 1
            if len(self.log) < self._log_limit:
                self.log.append(packet)
            for listener in self.packet_listeners:
                listener(now, packet)
            if self.wire_timing:
                t_free += wire_time_s(len(frame), self.baud_rate)
            chained = packet.instruction == Instruction1.BULK_READ
            for sid, reply in self._handle1(packet, now):
                delay = self._return_delay_s(sid) if self.wire_timing else 0.0
                mangled = self.faults.mangle(reply)
                if self.wire_timing:
                    t_free += delay + wire_time_s(len(reply), self.baud_rate)
                if mangled is None:
                    if chained:
                        break  # the next servo never hears the status it waits for
                    continue
                replies.append(Reply(t_free + self.faults.extra_latency_s, mangled))
                if chained and mangled != reply:
                    break
        if self.wire_timing:
            self._wire_free_s = t_free
        return replies

    def _listening(self, sid: int, now: float) -> EmulatedServo1 | None:  # type: ignore[override]
        s = self.servos.get(sid)
        if s is None or sid in self.faults.deaf_ids or now < s.boot_until_s:
            return None
        if BAUD_RATE_BY_INDEX_1.get(s.get("baud_rate")) != self.baud_rate:
            return None
        return s  # type: ignore[return-value]

    def _handle1(self, p: Packet, now: float) -> list[tuple[int, bytes]]:
        inst, params = p.instruction, p.params
        out: list[tuple[int, bytes]] = []
        if inst in _SINGLE:
            targets = sorted(self.servos) if p.servo_id == BROADCAST_ID else [p.servo_id]
            for sid in targets:
                s = self._listening(sid, now)
                if s is None:
                    continue
                reply = self._single1(s, p, now)
                if reply is None or sid in self.faults.silent_ids:
                    continue
                if p.servo_id == BROADCAST_ID and inst != Instruction1.PING:
                    continue  # broadcast: no status except for ping
                out.append((sid, reply))
            return out
        if inst == Instruction1.SYNC_WRITE and len(params) >= 2:
            address, length = params[0], params[1]
            body = params[2:]
            step = 1 + length
            if length == 0 or len(body) % step:
                return out
            for k in range(0, len(body), step):
                s = self._listening(body[k], now)
                if s is not None:
                    s.write(address, body[k + 1 : k + step], now)
            return out
        if inst == Instruction1.BULK_READ:
            try:
                items = parse_bulk_read_params1(params)
            except ProtocolError:
                return out
            for sid, address, length in items:
                s = self._listening(sid, now)
                if s is None or not s.table.bulk_read or sid in self.faults.silent_ids or not self._answers(s, is_read=True):
                    break  # the rest of the list waits for this servo's status
                err, data = s.read(address, length)
                out.append((sid, encode_status1(sid, err, data if len(data) == length else bytes(length))))
            return out
        if p.servo_id != BROADCAST_ID:  # unknown instruction: Instruction Error
            s = self._listening(p.servo_id, now)
            if s is not None and self._answers(s) and p.servo_id not in self.faults.silent_ids:
                out.append((s.id, encode_status1(s.id, ErrorBits1.INSTRUCTION | s.alert)))
        return out

    def _single1(self, s: EmulatedServo1, p: Packet, now: float) -> bytes | None:
        inst, params = p.instruction, p.params
        sid = s.id
        if inst == Instruction1.PING:
            return encode_status1(sid, s.alert)  # PING answers whatever Status Return Level says
        if inst == Instruction1.READ:
            if len(params) != 2:
                err, data = ErrorBits1.INSTRUCTION | s.alert, b""
            else:
                err, data = s.read(params[0], params[1])
            return encode_status1(sid, err, data) if self._answers(s, is_read=True) else None
        if inst == Instruction1.WRITE:
            if len(params) < 2:
                err = ErrorBits1.INSTRUCTION | s.alert
            else:
                old_id = s.id
                err = s.write(params[0], params[1:], now)
                if s.id != old_id:
                    self.servos[s.id] = self.servos.pop(old_id)
            return encode_status1(sid, err) if self._answers(s) else None
        if inst == Instruction1.REG_WRITE:
            if len(params) < 2:
                err = ErrorBits1.INSTRUCTION | s.alert
            else:
                s.registered = (params[0], bytes(params[1:]))
                s.mem[44] = 1
                err = s.alert
            return encode_status1(sid, err) if self._answers(s) else None
        if inst == Instruction1.ACTION:
            if s.registered is None:
                err = s.alert  # nothing registered: nothing happens
            else:
                address, data = s.registered
                s.registered = None
                s.mem[44] = 0
                err = s.write(address, data, now)
            return encode_status1(sid, err) if self._answers(s) else None
        if inst == Instruction1.RESET:
            reply = encode_status1(sid, s.alert) if self._answers(s) else None
            old_id = s.id
            s.reset()
            if s.id != old_id:
                self.servos[s.id] = self.servos.pop(old_id)
            return reply
        return encode_status1(sid, ErrorBits1.INSTRUCTION | s.alert) if self._answers(s) else None
