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

from drivers.clock import Clock
from drivers.control_table import control_table
from drivers.control_table1 import BAUD_INDEX_BY_RATE_1, BAUD_RATE_BY_INDEX_1
from drivers.errors import ProtocolError
from drivers.mockbus.emulated_servo1 import EmulatedServo1
from drivers.mockbus.emulator import _PLANT_PERIOD_S, MockBus, _apply_registered_write
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
    _baud_by_index = BAUD_RATE_BY_INDEX_1

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
        init = dict(initial_position_ticks or {})
        emulated = {}
        for sid, model in servos.items():
            table = control_table(model, 1.0)
            emulated[sid] = EmulatedServo1(sid, table, baud_index=BAUD_INDEX_BY_RATE_1[baud_rate],
                                           return_delay_units=return_delay_units,
                                           initial_position_ticks=init.get(sid, table.center_ticks),
                                           firmware_version=firmware_version)
        if plant is None:
            plant = KinematicPlant(initial_rad={sid: s.position_rad for sid, s in emulated.items()})
        # EmulatedServo1 has EmulatedServo's bus interface
        self._start(emulated, plant, None, PacketReader1(), baud_rate=baud_rate,  # type: ignore[arg-type]
                    clock=clock, faults=faults, wire_timing=wire_timing, boot_time_s=boot_time_s,
                    plant_period_s=plant_period_s)

    # ---- bytes in, replies out (MockBus.receive with these) ------------------------------
    def _decode(self, frame: bytes) -> Packet | None:
        try:
            return decode_instruction1(frame)
        except ProtocolError:
            return None

    def _chained(self, packet: Packet) -> bool:
        return packet.instruction == Instruction1.BULK_READ  # each status follows the one before it

    def _handle(self, p: Packet, now: float) -> list[tuple[int, bytes]]:
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
            self._sync_write(params[0], params[1], params[2:], now)
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
            err = _apply_registered_write(s, now, flag_address=44)  # type: ignore[arg-type]
            if err is None:
                err = s.alert  # nothing registered: nothing happens
            return encode_status1(sid, err) if self._answers(s) else None
        if inst == Instruction1.RESET:
            reply = encode_status1(sid, s.alert) if self._answers(s) else None
            old_id = s.id
            s.reset()
            if s.id != old_id:
                self.servos[s.id] = self.servos.pop(old_id)
            return reply
        return encode_status1(sid, ErrorBits1.INSTRUCTION | s.alert) if self._answers(s) else None
