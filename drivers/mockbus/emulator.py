"""The emulated bus: byte stream in, status packets out, time-stamped.

:class:`MockBus` owns the emulated servos, a :class:`~drivers.mockbus.plant.Plant`, a
:class:`~drivers.clock.Clock` and a :class:`~drivers.mockbus.faults.FaultInjector`. Feed it the
bytes a host writes with :meth:`MockBus.receive`; it returns the replies with the time at which
each is fully on the wire (wire timing at the bus baud rate and each servo's return delay, when
``wire_timing`` is on; otherwise immediately). Time evolves lazily: the plant, temperatures and
watchdogs are advanced to the clock's time whenever bytes arrive or :meth:`MockBus.advance` is
called.

An OP3's OpenCR sub-controller (:class:`~drivers.mockbus.emulated_imu.EmulatedImu`, ID 200,
model 0x7400) joins the bus when one is passed as ``imu``: it answers PING, READ, WRITE and its
items of a (plain) SYNC or BULK READ; its IMU registers come from the plant's IMU hook
(:func:`~drivers.mockbus.plant.imu_source_of`: the physics twin) at the time of each read.
"""

from __future__ import annotations

import logging
import struct
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, replace

from drivers.clock import Clock, MonotonicClock
from drivers.control_table import BAUD_INDEX_BY_RATE, BAUD_RATE_BY_INDEX, CENTER_TICKS, RAD_PER_TICK, control_table
from drivers.mockbus.faults import FaultInjector
from drivers.mockbus.plant import KinematicPlant, Plant, ServoMotion, imu_source_of
from drivers.mockbus.emulated_imu import EmulatedImu
from drivers.mockbus.emulated_servo import EmulatedServo
from drivers.protocol import (
    BROADCAST_ID,
    FrameReader,
    Instruction,
    Packet,
    PacketReader,
    StatusError,
    decode_packet,
    encode_fast_sync_status,
    encode_status,
    wire_time_s,
)

__all__ = ["MockBus", "Reply", "BAUD_BY_INDEX"]

_log = logging.getLogger(__name__)

BAUD_BY_INDEX = BAUD_RATE_BY_INDEX  # re-exported for emulator users
_MAX_STEP_S = 0.01  # [s] largest plant integration step
_PLANT_PERIOD_S = 0.002  # [s] smallest plant step (500 Hz, the MuJoCo twin's physics rate)


@dataclass(frozen=True)
class Reply:
    """Bytes the servos put on the wire, complete at ``ready_s`` [s] on the bus clock."""

    ready_s: float
    data: bytes


class MockBus:
    """A byte-level Protocol 2.0 bus with emulated X-series servos.

    Args:
        servos: ``{id: model}`` of the servos on the bus.
        baud_rate: bus speed [bit/s]; servos answer only if their Baud Rate register matches.
        clock: time source (``FakeClock`` for deterministic tests).
        plant: what moves the shafts (default :class:`KinematicPlant`).
        faults: fault injector (default: none).
        wire_timing: delay replies by their wire time and return delay.
        return_delay_units: initial Return Delay Time of every servo (2 us units).
        initial_position_ticks: initial shaft positions by ID.
        firmware_version: firmware every servo reports.
        boot_time_s: how long a rebooting servo stays silent [s].
        plant_period_s: shortest plant step [s]; present values are at most this old.
        imu: an OpenCR sub-controller on the bus (its ID must not be a servo's); fed by the
            plant's IMU hook unless it has a source of its own.
    """

    _baud_by_index: Mapping[int, int] = BAUD_RATE_BY_INDEX  # Baud Rate register value -> bit/s

    def __init__(self, servos: Mapping[int, str], *, baud_rate: int = 1_000_000,
                 clock: Clock | None = None, plant: Plant | None = None,
                 faults: FaultInjector | None = None, wire_timing: bool = False,
                 return_delay_units: int = 0, initial_position_ticks: Mapping[int, int] | None = None,
                 firmware_version: int = 46, boot_time_s: float = 0.05,
                 plant_period_s: float = _PLANT_PERIOD_S, imu: EmulatedImu | None = None) -> None:
        if baud_rate not in BAUD_INDEX_BY_RATE:
            raise ValueError(f"baud_rate {baud_rate} not in {sorted(BAUD_INDEX_BY_RATE)}")
        init = dict(initial_position_ticks or {})
        emulated = {sid: EmulatedServo(sid, control_table(model), baud_index=BAUD_INDEX_BY_RATE[baud_rate],
                                       return_delay_units=return_delay_units,
                                       initial_position_ticks=init.get(sid, CENTER_TICKS),
                                       firmware_version=firmware_version)
                    for sid, model in servos.items()}
        if plant is None:
            plant = KinematicPlant(initial_rad={
                sid: (init.get(sid, CENTER_TICKS) - CENTER_TICKS) * RAD_PER_TICK for sid in servos})
        if imu is not None:
            if imu.id in emulated:
                raise ValueError(f"the IMU's ID {imu.id} is a servo's")
            imu.set("baud_rate", BAUD_INDEX_BY_RATE[baud_rate])  # configured for the bus, as on the robot
            if imu.source is None:
                imu.source = imu_source_of(plant)
        self._start(emulated, plant, imu, PacketReader(), baud_rate=baud_rate, clock=clock, faults=faults,
                    wire_timing=wire_timing, boot_time_s=boot_time_s, plant_period_s=plant_period_s)

    def _start(self, servos: Mapping[int, EmulatedServo], plant: Plant, imu: EmulatedImu | None,
               reader: FrameReader, *, baud_rate: int, clock: Clock | None, faults: FaultInjector | None,
               wire_timing: bool, boot_time_s: float, plant_period_s: float) -> None:
        """The state of a bus of ``servos`` whatever its protocol (``reader``: its codec's frame
        reader); the other arguments as in the constructor."""
        self.baud_rate = baud_rate
        self.clock: Clock = clock or MonotonicClock()
        self.faults = faults or FaultInjector()
        self.wire_timing = wire_timing
        self.boot_time_s = boot_time_s
        self.plant_period_s = plant_period_s
        self.servos: dict[int, EmulatedServo] = dict(servos)
        self.plant = plant
        self.imu = imu
        self._reader = reader
        self._last_s = self.clock.now()
        self._wire_free_s = self._last_s  # [s] when the last packet or reply leaves the wire
        for s in self.servos.values():
            s.start_s = self._last_s
            s.watchdog_last_feed_s = self._last_s
        self.packets_received = 0
        self.log: list[Packet] = []  # every instruction packet received (bounded)
        self._log_limit = 10000
        # called with (arrival time [s], packet) for every instruction packet received, unbounded
        # (a spy that checks every goal a long run writes; the log above keeps the first 10000)
        self.packet_listeners: list[Callable[[float, Packet], None]] = []

    # ---- time ------------------------------------------------------------------------
    def advance(self, now_s: float | None = None) -> None:
        """Advance plant, temperatures, scheduled faults and watchdogs to ``now_s``."""
        now = self.clock.now() if now_s is None else now_s
        # the plant moves in steps of at least plant_period_s (a servo's own control period):
        # stepping 20 servos on every received packet would cost more than the wire time
        while now - self._last_s >= self.plant_period_s:
            step_end = min(now, self._last_s + _MAX_STEP_S)
            for f in self.faults.due(step_end):
                f.action(self)
            # watchdog trips inside this step happen at their deadline
            for s in self.servos.values():
                deadline = s.watchdog_deadline()
                if deadline is not None and deadline <= step_end:
                    step_end = max(deadline, self._last_s)
            self._step(step_end - self._last_s, step_end)
            self._last_s = step_end
            for s in self.servos.values():
                deadline = s.watchdog_deadline()
                if deadline is not None and deadline <= step_end:
                    s.trip_watchdog()
        for f in self.faults.due(now):
            f.action(self)

    def _step(self, dt: float, now: float) -> None:
        for sid, bits in list(self.faults.pending_hardware_errors.items()):
            if sid in self.servos:
                self.servos[sid].raise_hardware_error(bits)
            del self.faults.pending_hardware_errors[sid]
        commands = {sid: s.command() for sid, s in self.servos.items()}
        stuck = self.faults.stuck_ids
        # a blocked shaft does not move, powered or not: the plant (the physics twin) is asked to
        # hold it where it was blocked, so the body agrees with what the servo reports
        to_plant = commands if not stuck else {
            sid: replace(c, torque_on=True, goal_rad=self.servos[sid].position_rad, pwm_fraction=1.0)
            if sid in stuck else c for sid, c in commands.items()}
        motions = self.plant.advance(dt, to_plant)
        for sid, s in self.servos.items():
            m = motions.get(sid)
            if sid in stuck:  # blocked shaft: no motion; the motor pushes toward its goal
                c = commands[sid]
                push = c.stiffness_nm_per_rad * (c.goal_rad - s.position_rad) if c.torque_on else 0.0
                push = max(-c.stall_torque_nm, min(c.stall_torque_nm, push)) * c.pwm_fraction
                m = ServoMotion(s.position_rad, 0.0, push)
            if m is not None:
                s.apply_motion(m, dt, now, self.faults.voltage_of(sid), self.faults.heating_gain)

    # ---- bytes in, replies out -----------------------------------------------------------
    def receive(self, data: bytes, now_s: float | None = None) -> list[Reply]:
        """Process bytes written by the host at ``now_s``; return the replies, in wire order."""
        now = self.clock.now() if now_s is None else now_s
        self.advance(now)
        self._reader.feed(data)
        replies: list[Reply] = []
        # the wire is half duplex: a packet starts once the previous packets (and replies)
        # have left it, so back-to-back instructions queue behind each other
        t_free = max(now, self._wire_free_s) if self.wire_timing else now
        while True:
            frame = self._reader.next_frame()
            if frame is None:
                break
            packet = self._decode(frame)
            if packet is None:
                continue
            self.packets_received += 1
            if len(self.log) < self._log_limit:
                self.log.append(packet)
            for listener in self.packet_listeners:
                listener(now, packet)
            if self.wire_timing:
                t_free += wire_time_s(len(frame), self.baud_rate)
            chained = self._chained(packet)
            for sid, reply in self._handle(packet, now):
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

    def _decode(self, frame: bytes) -> Packet | None:
        """The instruction packet in ``frame``; ``None`` for one a servo would ignore."""
        try:
            return decode_packet(frame)
        except Exception:  # malformed after CRC passed (e.g. empty body): ignore like a servo
            return None

    def _chained(self, packet: Packet) -> bool:
        """Each reply to ``packet`` waits for the one before it (a lost one silences the rest)."""
        return False

    def _return_delay_s(self, sid: int) -> float:
        servo = self.servos.get(sid)
        if servo is not None:
            return servo.get("return_delay_time") * 2e-6
        if self.imu is not None and sid == self.imu.id:
            return self.imu.return_delay_s
        return 0.0

    def _imu_listening(self, sid: int) -> EmulatedImu | None:
        imu = self.imu
        if imu is None or sid != imu.id or sid in self.faults.deaf_ids:
            return None
        if BAUD_BY_INDEX.get(imu.get("baud_rate")) != self.baud_rate:
            return None
        return imu

    def _imu_answers(self, imu: EmulatedImu, *, is_read: bool = False) -> bool:
        if imu.id in self.faults.silent_ids:
            return False
        level = imu.get("status_return_level")
        return level >= 2 or (level == 1 and is_read)

    def _imu_single(self, imu: EmulatedImu, p: Packet) -> bytes | None:
        """PING, READ and WRITE of the OpenCR; other instructions are answered with an Instruction Error."""
        inst, params, iid = p.instruction, p.params, imu.id
        if inst == Instruction.PING:
            return None if iid in self.faults.silent_ids else encode_status(iid, 0, imu.ping_data())
        if inst == Instruction.READ:
            if len(params) != 4:
                err, data = int(StatusError.DATA_LENGTH), b""
            else:
                err, data = imu.read(*struct.unpack("<HH", params))
            return encode_status(iid, err, data) if self._imu_answers(imu, is_read=True) else None
        if inst == Instruction.WRITE:
            err = StatusError.DATA_LENGTH if len(params) < 3 else imu.write(params[0] | (params[1] << 8), params[2:])
            return encode_status(iid, err) if self._imu_answers(imu) else None
        return encode_status(iid, StatusError.INSTRUCTION) if self._imu_answers(imu) else None

    def _listening(self, sid: int, now: float) -> EmulatedServo | None:
        s = self.servos.get(sid)
        if s is None or sid in self.faults.deaf_ids or now < s.boot_until_s:
            return None
        if self._baud_by_index.get(s.get("baud_rate")) != self.baud_rate:
            return None
        return s

    def _answers(self, s: EmulatedServo, *, is_read: bool = False) -> bool:
        if s.id in self.faults.silent_ids:
            return False
        level = s.get("status_return_level")
        return level >= 2 or (level == 1 and is_read)

    def _handle(self, p: Packet, now: float) -> list[tuple[int, bytes]]:
        inst, params = p.instruction, p.params
        out: list[tuple[int, bytes]] = []
        targets: Iterable[int]
        if p.servo_id == BROADCAST_ID:
            targets = sorted([*self.servos, *([self.imu.id] if self.imu is not None else [])])
        else:
            targets = (p.servo_id,)
        if inst == Instruction.STATUS:
            return out
        # instructions addressed to one servo or broadcast-to-all
        if inst in (Instruction.PING, Instruction.READ, Instruction.WRITE, Instruction.REG_WRITE,
                    Instruction.ACTION, Instruction.REBOOT, Instruction.FACTORY_RESET, Instruction.CLEAR):
            for sid in targets:
                imu = self._imu_listening(sid)
                if imu is not None:
                    reply = self._imu_single(imu, p)
                    if reply is not None and (p.servo_id != BROADCAST_ID or inst == Instruction.PING):
                        out.append((imu.id, reply))
                    continue
                s = self._listening(sid, now)
                if s is None:
                    continue
                s.feed_watchdog(now)
                reply = self._single(s, p, now)
                if reply is None or s.id in self.faults.silent_ids:
                    continue
                if p.servo_id == BROADCAST_ID and inst != Instruction.PING:
                    continue  # broadcast: no status except for ping
                out.append((s.id, reply))
            return out
        if inst in (Instruction.SYNC_READ, Instruction.FAST_SYNC_READ) and len(params) >= 4:
            address, length = struct.unpack_from("<HH", params)
            ids = list(params[4:])
            return self._sync_read(ids, [(address, length)] * len(ids), now,
                                   fast=inst == Instruction.FAST_SYNC_READ)
        if inst in (Instruction.BULK_READ, Instruction.FAST_BULK_READ) and len(params) % 5 == 0:
            items = [struct.unpack_from("<BHH", params, k) for k in range(0, len(params), 5)]
            return self._sync_read([i for i, _, _ in items], [(a, n) for _, a, n in items], now,
                                   fast=inst == Instruction.FAST_BULK_READ)
        if inst == Instruction.SYNC_WRITE and len(params) >= 4:
            address, length = struct.unpack_from("<HH", params)
            self._sync_write(address, length, params[4:], now)
            return out
        if inst == Instruction.BULK_WRITE:
            k = 0
            while k + 5 <= len(params):
                sid, address, length = struct.unpack_from("<BHH", params, k)
                data = params[k + 5 : k + 5 + length]
                k += 5 + length
                s = self._listening(sid, now)
                if s is not None and len(data) == length:
                    s.feed_watchdog(now)
                    s.write(address, data, now)
            return out
        # unknown instruction: unicast answers Instruction Error
        if p.servo_id != BROADCAST_ID:
            imu = self._imu_listening(p.servo_id)
            if imu is not None:
                if self._imu_answers(imu):
                    out.append((imu.id, encode_status(imu.id, StatusError.INSTRUCTION)))
                return out
            s = self._listening(p.servo_id, now)
            if s is not None and self._answers(s):
                out.append((s.id, encode_status(s.id, StatusError.INSTRUCTION | s.alert)))
        return out

    def _sync_write(self, address: int, length: int, body: bytes, now: float) -> None:
        """A SYNC_WRITE's ``body`` (per servo: ID, then ``length`` bytes) written to each listening
        servo at ``address``; a body of the wrong size is ignored, as a servo does."""
        step = 1 + length
        if length == 0 or len(body) % step:
            return
        for k in range(0, len(body), step):
            s = self._listening(body[k], now)
            if s is not None:
                s.feed_watchdog(now)
                s.write(address, body[k + 1 : k + step], now)

    def _single(self, s: EmulatedServo, p: Packet, now: float) -> bytes | None:
        inst, params = p.instruction, p.params
        sid = s.id
        if inst == Instruction.PING:
            if s.id in self.faults.silent_ids:
                return None
            fw = s.get("firmware_version")
            return encode_status(sid, s.alert, struct.pack("<HB", s.get("model_number"), fw))
        if inst == Instruction.READ:
            if len(params) != 4:
                return encode_status(sid, StatusError.DATA_LENGTH | s.alert) if self._answers(s, is_read=True) else None
            address, length = struct.unpack("<HH", params)
            err, data = s.read(address, length)
            return encode_status(sid, err, data) if self._answers(s, is_read=True) else None
        if inst == Instruction.WRITE:
            if len(params) < 3:
                err = StatusError.DATA_LENGTH | s.alert
            else:
                address = params[0] | (params[1] << 8)
                old_id = s.id
                err = s.write(address, params[2:], now)
                if s.id != old_id:
                    self.servos[s.id] = self.servos.pop(old_id)
            return encode_status(sid, err) if self._answers(s) else None
        if inst == Instruction.REG_WRITE:
            if len(params) < 3:
                err = StatusError.DATA_LENGTH | s.alert
            else:
                s.registered = (params[0] | (params[1] << 8), bytes(params[2:]))
                s.mem[69] = 1
                err = s.alert
            return encode_status(sid, err) if self._answers(s) else None
        if inst == Instruction.ACTION:
            err = _apply_registered_write(s, now, flag_address=69)
            if err is None:
                err = StatusError.RESULT_FAIL | s.alert
            return encode_status(sid, err) if self._answers(s) else None
        if inst == Instruction.REBOOT:
            reply = encode_status(sid, s.alert) if self._answers(s) else None
            s.reboot(now, self.boot_time_s)
            return reply
        return encode_status(sid, StatusError.INSTRUCTION | s.alert) if self._answers(s) else None

    def _sync_read(self, ids: list[int], spans: list[tuple[int, int]], now: float,
                   *, fast: bool) -> list[tuple[int, bytes]]:
        blocks: list[tuple[int, int, bytes]] = []
        out: list[tuple[int, bytes]] = []
        broken = False
        for sid, (address, length) in zip(ids, spans):
            imu = self._imu_listening(sid)
            if imu is not None:  # the OpenCR answers plain sync / bulk reads only
                if fast or not self._imu_answers(imu, is_read=True):
                    broken = True
                    continue
                err, data = imu.read(address, length)
                out.append((sid, encode_status(sid, err, data if len(data) == length else bytes(length))))
                continue
            s = self._listening(sid, now)
            if s is None:
                broken = True
                continue
            s.feed_watchdog(now)
            if fast and s.get("firmware_version") < s.table.fast_sync_read_min_firmware:
                return []
            if not self._answers(s, is_read=True):
                broken = True
                continue
            err, data = s.read(address, length)
            if len(data) != length:
                data = bytes(length)
            if fast:
                blocks.append((sid, err, data))
            else:
                out.append((sid, encode_status(sid, err, data)))
        if not fast:
            return out
        if not blocks:
            return []
        frame = encode_fast_sync_status(blocks)
        if broken:
            # A missing servo leaves a hole: the length field was announced for every servo,
            # so the host sees a short (timed out) frame.
            n_missing = len(ids) - len(blocks)
            length_field = frame[5] | (frame[6] << 8)
            length_field += sum(4 + n for (_, n) in spans[: n_missing])
            frame = frame[:5] + bytes((length_field & 0xFF, length_field >> 8)) + frame[7:]
        return [(blocks[0][0], frame)]

    # ---- conveniences for tests and tools -------------------------------------------------
    def servo(self, servo_id: int) -> EmulatedServo:
        return self.servos[servo_id]

    @classmethod
    def from_ids(cls, ids: Iterable[int], model: str = "XM430-W350", **kwargs: object) -> "MockBus":
        """A bus with ``model`` servos at ``ids`` (keyword arguments as in the constructor)."""
        return cls({i: model for i in ids}, **kwargs)  # type: ignore[arg-type]


def _apply_registered_write(s: EmulatedServo, now: float, *, flag_address: int) -> int | None:
    """ACTION on ``s``: the write its REG_WRITE registered, done now; its status error bits, or
    ``None`` when nothing was registered. The Registered Instruction flag at ``flag_address``
    reads 0 again."""
    if s.registered is None:
        return None
    address, data = s.registered
    s.registered = None
    s.mem[flag_address] = 0
    return s.write(address, data, now)
