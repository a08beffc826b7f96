"""``ServoGroup``: the servos of one servo map on one bus, in joint units.

Owns the per-cycle I/O: one sync write of goal positions and one (fast, where every servo's
firmware supports it, else plain) sync read of the feedback block, which indirect addressing
packs into 14 contiguous bytes at Indirect Data 1 (address 224):

    present_position (4) | present_velocity (4) | present_current/load (2) |
    hardware_error_status (1) | present_temperature (1) | present_input_voltage (2)

Isolation: a failed Fast Sync Read falls back to a plain Sync Read, which yields partial
results; a servo without data for ``quarantine_after`` cycles is quarantined (left out of the
group reads so it no longer costs a timeout every cycle) and re-pinged every
``reping_every`` cycles.
"""

from __future__ import annotations

import logging
import struct
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivers.bus import DynamixelBus, GroupRead
from drivers.control_table import (
    INDIRECT_ADDRESS_1,
    INDIRECT_DATA_1,
    VOLTAGE_UNIT_V,
    ControlTable,
    control_table,
)
from drivers.errors import ControlTableError
from drivers.protocol import BITS_PER_BYTE
from drivers.servo_map import ServoMap

__all__ = ["FEEDBACK_LAYOUT", "FEEDBACK_SIZE", "Feedback", "ServoGroup"]

_log = logging.getLogger(__name__)

# Group instructions address every servo at once, so the registers used here are looked up in
# one table: every supported model shares the X-series layout (drivers/control_table.py), which
# ServoGroup checks for the models of its map (_check_layout).
_LAYOUT: ControlTable = control_table("XM430-W350")
_FEEDBACK_REGISTERS = ("present_position", "present_velocity", "present_current", "hardware_error_status",
                       "present_temperature", "present_input_voltage")
# (register address, size) packed by indirect addressing, in order
FEEDBACK_LAYOUT: tuple[tuple[int, int], ...] = tuple(
    (_LAYOUT[name].address, _LAYOUT[name].size) for name in _FEEDBACK_REGISTERS)
FEEDBACK_SIZE = sum(n for _, n in FEEDBACK_LAYOUT)  # 14 bytes
_FEEDBACK_STRUCT = struct.Struct("<iihBBH")
# one servo's block of a Fast Sync Read reply: error, id, the feedback layout, running CRC
_FAST_BLOCK = np.dtype([("error", "u1"), ("id", "u1"), ("pos", "<i4"), ("vel", "<i4"), ("cur", "<i2"),
                        ("hw", "u1"), ("temp", "u1"), ("volt", "<u2"), ("crc", "<u2")])
_GOAL_BLOCK = np.dtype([("id", "u1"), ("ticks", "<i4")])  # one servo's sync-write goal entry
GOAL_POSITION = _LAYOUT["goal_position"].address
TORQUE_ENABLE = _LAYOUT["torque_enable"].address
GOAL_PWM = _LAYOUT["goal_pwm"].address
GOAL_PWM_SIZE = _LAYOUT["goal_pwm"].size
BUS_WATCHDOG = _LAYOUT["bus_watchdog"].address
# without the indirect block: one contiguous read from Present Current through address 147 (one
# byte past Present Temperature, read since the start, not decoded), then Hardware Error Status
_SPAN_ADDRESS = _LAYOUT["present_current"].address
_SPAN_SIZE = _LAYOUT["present_temperature"].address + _LAYOUT["present_temperature"].size + 1 - _SPAN_ADDRESS
_SPAN_REGISTERS = tuple(_LAYOUT[name] for name in ("present_position", "present_velocity", "present_current",
                                                   "present_temperature", "present_input_voltage"))
_HARDWARE_ERROR = _LAYOUT["hardware_error_status"]
_USED_REGISTERS = tuple(_LAYOUT[name] for name in (*_FEEDBACK_REGISTERS, "goal_position", "torque_enable",
                                                   "goal_pwm", "bus_watchdog", "pwm_limit"))


def _check_layout(table: ControlTable) -> None:
    """Raise unless ``table`` has every register used here at the shared address and size."""
    for reg in _USED_REGISTERS:
        other = table.at(reg.address)
        if other is None or other.size != reg.size:
            raise ControlTableError(f"{table.model} has no {reg.size}-byte register at {reg.address} ({reg.name})",
                                    hint="a servo group needs the X-series layout on every servo")


@dataclass(frozen=True)
class Feedback:
    """One cycle's feedback in servo-map order; entries not read this cycle are NaN / 0.

    Attributes:
        t_s: clock time of the read [s].
        position_rad: joint angles [rad], shape (n,).
        velocity_rad_s: joint velocities [rad/s], shape (n,).
        effort_raw: present current (2.69 mA units) or load (0.1 %) as read, shape (n,).
        hardware_error: Hardware Error Status bits, shape (n,) int.
        error_byte: status error byte per servo (bit 7 = alert), shape (n,) int.
        temperature_c: [degC], shape (n,).
        voltage_v: [V], shape (n,).
        valid: data read this cycle, shape (n,) bool.
    """

    t_s: float
    position_rad: NDArray[np.float64]
    velocity_rad_s: NDArray[np.float64]
    effort_raw: NDArray[np.float64]
    hardware_error: NDArray[np.int64]
    error_byte: NDArray[np.int64]
    temperature_c: NDArray[np.float64]
    voltage_v: NDArray[np.float64]
    valid: NDArray[np.bool_]

    @property
    def alert(self) -> NDArray[np.int64]:
        """Hardware error bits, or 0x80 where only the status alert bit reported one."""
        return np.where(self.hardware_error != 0, self.hardware_error, self.error_byte & 0x80)


def _empty_columns(n: int) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64], NDArray[np.int64],
                                     NDArray[np.int64], NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """One read's per-servo columns before any reply, shape (n,) each: raw position and velocity
    (0), effort (NaN), hardware error and status error bits (0), temperature and voltage (NaN),
    valid (False)."""
    return (np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64), np.full(n, np.nan),
            np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64), np.full(n, np.nan), np.full(n, np.nan),
            np.zeros(n, dtype=bool))


class _ServoGroupBase:
    """What the Protocol 2.0 and 1.0 groups share: the map, writes of one register on many
    servos, and the quarantine of silent servos with their re-pings.

    Args:
        bus: the bus of the group's protocol.
        servo_map: which IDs, joints, directions and limits.
        check_layout: raises unless a table has every register the group uses.
        quarantine_after: consecutive missing reads before a servo is quarantined.
        reping_every: cycles between re-pings of quarantined servos.
    """

    def __init__(self, bus: DynamixelBus, servo_map: ServoMap, *, check_layout: Callable[[ControlTable], None],
                 quarantine_after: int, reping_every: int) -> None:
        for table in {s.table.model: s.table for s in servo_map.servos}.values():
            check_layout(table)
        self.bus = bus
        self.map = servo_map
        self.ids = servo_map.ids
        self.quarantine_after = quarantine_after
        self.reping_every = reping_every
        self.consecutive_failures = np.zeros(len(self.ids), dtype=np.int64)
        self.quarantined: set[int] = set()
        self.readmitted: set[int] = set()  # servos back from quarantine since the last read
        self._cycle = 0
        self._index = {sid: k for k, sid in enumerate(self.ids)}

    def write_all(self, address: int, size: int, value: int, ids: Sequence[int] | None = None, *,
                  quarantined_too: bool = False) -> None:
        """Sync-write the same raw ``value`` to a register span on ``ids`` (``None``: every
        servo; an empty sequence: none, nothing is sent). Quarantined servos are left out
        unless ``quarantined_too`` (a stop: one whose replies are lost may still listen)."""
        self.write_each(address, size, {sid: value for sid in (self.ids if ids is None else ids)},
                        quarantined_too=quarantined_too)

    def write_each(self, address: int, size: int, values: Mapping[int, int], *,
                   quarantined_too: bool = False) -> None:
        """Sync-write each servo's own raw value (``values``: ID -> value) to a register span."""
        mask = (1 << (8 * size)) - 1
        self.bus.sync_write(address, size, {sid: (int(v) & mask).to_bytes(size, "little") for sid, v in values.items()
                                            if quarantined_too or sid not in self.quarantined})

    def _start_read(self) -> None:
        """Count the cycle; every ``reping_every`` cycles, ping the quarantined servos."""
        self._cycle += 1
        self.readmitted = set()
        if self.quarantined and self._cycle % self.reping_every == 0:
            self._reping()

    def _count_failures(self, valid: NDArray[np.bool_], missing: Sequence[int]) -> None:
        """Update the consecutive failures (``valid``: shape (n,)) and quarantine the ``missing``."""
        self.consecutive_failures = np.where(valid, 0, self.consecutive_failures + 1)
        self._quarantine(missing)

    def _quarantine(self, missing: Sequence[int]) -> None:
        for sid in missing:
            k = self._index[sid]
            if self.consecutive_failures[k] >= self.quarantine_after and sid not in self.quarantined:
                _log.warning("servo %d (%s) quarantined after %d missed reads", sid,
                             self.map.servos[k].joint, self.consecutive_failures[k])
                self.quarantined.add(sid)

    def _reping(self) -> None:
        for sid in sorted(self.quarantined):
            if self.bus.ping(sid) is not None:
                _log.warning("servo %d answers again; re-admitted", sid)
                self.quarantined.discard(sid)
                self.readmitted.add(sid)


class ServoGroup(_ServoGroupBase):
    """The servos of ``servo_map`` on ``bus``, spoken to in radians.

    Args:
        bus: the :class:`DynamixelBus`.
        servo_map: which IDs, joints, directions and limits.
        fast_read: use Fast Sync Read (set by :func:`drivers.startup.preflight` from firmware).
        use_indirect: read the packed indirect block (set up by preflight); otherwise read
            the contiguous span 126..147 (Present Current to Present Temperature) plus hardware
            error status separately.
        quarantine_after: consecutive missing reads before a servo is quarantined.
        reping_every: cycles between re-pings of quarantined servos.
    """

    protocol = 2.0
    has_watchdog = True  # the X series' Bus Watchdog (address 98)
    ramp_register = _LAYOUT["goal_pwm"]  # what a LIMP stop ramps to 0
    ramp_limit_register = "pwm_limit"  # where the ramp starts, per servo

    def __init__(self, bus: DynamixelBus, servo_map: ServoMap, *, fast_read: bool = False,
                 use_indirect: bool = True, quarantine_after: int = 2, reping_every: int = 10) -> None:
        super().__init__(bus, servo_map, check_layout=_check_layout, quarantine_after=quarantine_after,
                         reping_every=reping_every)
        self.fast_read = fast_read
        self.use_indirect = use_indirect
        self._goal_reg = struct.Struct("<i")
        n = len(self.ids)
        self._ids_array = np.array(self.ids, dtype=np.uint8)
        self._ids_bytes = self._ids_array.tobytes()
        self._ids_tuple = tuple(self.ids)
        # goal sync write for all servos: the parameter block is a numpy record array whose
        # header (address, length) and IDs are filled once; only the ticks change per cycle
        self._goal_header = struct.pack("<HH", GOAL_POSITION, _LAYOUT["goal_position"].size)
        self._goal_block = np.zeros(n, dtype=_GOAL_BLOCK)
        self._goal_block["id"] = self._ids_array

    def cycle_wire_time_s(self) -> float:
        """Wire time of one cycle [s]: goal sync write + feedback read of every servo, with each
        servo's return delay (no byte stuffing assumed). ``1 / this`` is the highest rate the
        bus allows."""
        n = len(self.ids)
        write_b = 14 + 5 * n
        request_b = 14 + n
        if self.fast_read and self.use_indirect:
            reply_b = 8 + n * (4 + FEEDBACK_SIZE)
        elif self.use_indirect:
            reply_b = n * (11 + FEEDBACK_SIZE)
        else:  # 22-byte span and hardware error status, two plain sync reads
            reply_b = n * (11 + _SPAN_SIZE) + (14 + n) + n * (11 + _HARDWARE_ERROR.size)
        delays = n * self.map.bus.return_delay_time_us * 1e-6
        return (write_b + request_b + reply_b) * BITS_PER_BYTE / self.bus.baud_rate + delays

    # ---- configuration helpers ----------------------------------------------------------
    def indirect_address_items(self) -> list[tuple[int, bytes]]:
        """(address, data) writes that map the feedback block onto Indirect Data 1..14."""
        out = []
        k = 0
        for address, size in FEEDBACK_LAYOUT:
            for b in range(size):
                out.append((INDIRECT_ADDRESS_1 + 2 * k, struct.pack("<H", address + b)))
                k += 1
        return out

    # ---- writes ---------------------------------------------------------------------------
    def write_goals(self, q_rad: NDArray[np.float64], *, skip: Sequence[int] = (),
                    defer: bool = False) -> NDArray[np.int64]:
        """Sync-write goal positions for joint angles ``q_rad`` [rad], shape (n,).

        Quarantined servos and ``skip`` IDs are left out. With ``defer`` the frame leaves with
        the next instruction (the feedback read) in one ``write()``. Returns the ticks sent,
        shape (n,).
        """
        ticks = self.map.to_ticks(q_rad)
        if not self.quarantined and not skip:
            block = self._goal_block
            block["ticks"] = ticks
            self.bus.sync_write_params(self._goal_header + block.tobytes(), defer=defer)
            return ticks
        pack = self._goal_reg.pack
        data = {sid: pack(int(t)) for sid, t in zip(self.ids, ticks)
                if sid not in self.quarantined and sid not in skip}
        self.bus.sync_write(GOAL_POSITION, _LAYOUT["goal_position"].size, data, defer=defer)
        return ticks

    def torque(self, on: bool, ids: Sequence[int] | None = None, *, quarantined_too: bool = False) -> None:
        """Torque Enable on all (``ids`` None) or on ``ids`` only (empty: none) by sync write."""
        self.write_all(TORQUE_ENABLE, _LAYOUT["torque_enable"].size, int(on), ids, quarantined_too=quarantined_too)

    def read_each(self, name: str) -> dict[int, int]:
        """One plain sync read of register ``name`` from every active servo: ID -> raw value
        (servos that did not answer are absent)."""
        reg = _LAYOUT[name]
        r = self.bus.sync_read(reg.address, reg.size, [sid for sid in self.ids if sid not in self.quarantined])
        return {sid: reg.decode(d) for sid, d in r.data.items()}

    # ---- reads ----------------------------------------------------------------------------
    def _raw_read(self, ids: list[int]) -> GroupRead:
        if self.use_indirect:
            if self.fast_read:
                r = self.bus.sync_read(INDIRECT_DATA_1, FEEDBACK_SIZE, ids, fast=True)
                if r.complete:
                    return r
                _log.debug("fast sync read incomplete (%s); falling back to sync read", r.missing)
                if r.data:  # partial fast data (error bytes) is still usable
                    rest = [i for i in ids if i not in r.data]
                    r2 = self.bus.sync_read(INDIRECT_DATA_1, FEEDBACK_SIZE, rest)
                    return GroupRead({**r.data, **r2.data}, {**r.errors, **r2.errors}, r2.missing)
            return self.bus.sync_read(INDIRECT_DATA_1, FEEDBACK_SIZE, ids)
        # no indirect block: the contiguous span (126..147) then hardware errors
        r = self.bus.sync_read(_SPAN_ADDRESS, _SPAN_SIZE, ids, fast=self.fast_read)
        if self.fast_read and not r.complete:
            r = self.bus.sync_read(_SPAN_ADDRESS, _SPAN_SIZE, ids)
        hw = self.bus.sync_read(_HARDWARE_ERROR.address, _HARDWARE_ERROR.size, [i for i in ids if i in r.data])
        data = {}
        for sid, d in r.data.items():
            pos, vel, cur, temp, volt = (reg.decode(d[reg.address - _SPAN_ADDRESS:][:reg.size])
                                         for reg in _SPAN_REGISTERS)
            err = _HARDWARE_ERROR.decode(hw.data.get(sid, bytes(_HARDWARE_ERROR.size)))
            data[sid] = _FEEDBACK_STRUCT.pack(pos, vel, cur, err, temp, volt)
        return GroupRead(data, r.errors, r.missing, r.fast)

    def _fast_feedback(self) -> Feedback | None:
        """The hot path: one Fast Sync Read of every servo decoded with one numpy view."""
        return self.decode_fast_feedback(
            self.bus.fast_sync_read_raw(INDIRECT_DATA_1, FEEDBACK_SIZE, self._ids_tuple))

    # ---- pipelined cycle: the next request leaves before this reply is decoded ------------
    @property
    def pipelinable(self) -> bool:
        """Fast Sync Read of the indirect block, every servo active: the split cycle works."""
        return self.fast_read and self.use_indirect and not self.quarantined

    def request_fast_feedback(self) -> None:
        """Send the Fast Sync Read request of every servo (with deferred goal writes) and return
        without waiting; collect the reply with :meth:`collect_fast_feedback_raw` before any
        other instruction (the bus is half duplex).

        With :meth:`write_goals` (``defer=True``) called for the *next* cycle while this
        reply is on the wire, and the decode (:meth:`decode_fast_feedback`) done after the
        next request has left, the host's work leaves the wire's critical path.
        """
        self.bus.send_fast_sync_read(INDIRECT_DATA_1, FEEDBACK_SIZE, self._ids_tuple)

    def collect_fast_feedback_raw(self) -> bytes | None:
        """The validated raw reply to :meth:`request_fast_feedback` (``None``: failed)."""
        return self.bus.receive_fast_sync_read(FEEDBACK_SIZE, self._ids_tuple)

    def decode_fast_feedback(self, raw: bytes | None) -> Feedback | None:
        """Decode a raw Fast Sync Read reply of every servo; ``None`` if absent or out of order.

        Updates the per-servo failure counts and quarantines servos that answered with an error
        number, as :meth:`read_feedback` does.
        """
        if raw is None:
            return None
        blocks = np.frombuffer(raw, dtype=_FAST_BLOCK, count=len(self.ids), offset=8)
        if blocks["id"].tobytes() != self._ids_bytes:
            _log.debug("fast sync read blocks out of order: %s", blocks["id"])
            return None
        err = blocks["error"].astype(np.int64)
        now = self.bus.clock.now()
        if not (err & 0x7F).any():  # the usual case: every servo answered without an error
            self.consecutive_failures[:] = 0
            return Feedback(now, self.map.to_radians(blocks["pos"]), self.map.velocity_to_rad_s(blocks["vel"]),
                            blocks["cur"].astype(np.float64), blocks["hw"].astype(np.int64), err,
                            blocks["temp"].astype(np.float64), blocks["volt"] * VOLTAGE_UNIT_V,
                            np.ones(len(self.ids), dtype=bool))
        valid = (err & 0x7F) == 0
        hw = np.where(valid, blocks["hw"], 0).astype(np.int64)
        self._count_failures(valid, [sid for sid, ok in zip(self.ids, valid) if not ok])
        q = np.where(valid, self.map.to_radians(blocks["pos"]), np.nan)
        qd = np.where(valid, self.map.velocity_to_rad_s(blocks["vel"]), np.nan)
        eff = np.where(valid, blocks["cur"], np.nan)
        temp = np.where(valid, blocks["temp"], np.nan)
        volt = np.where(valid, blocks["volt"] * VOLTAGE_UNIT_V, np.nan)
        return Feedback(now, q, qd, eff, hw, err, temp, volt, valid)

    def read_feedback(self) -> Feedback:
        """One group read of the feedback block of every active servo, in joint units."""
        self._start_read()
        if self.fast_read and self.use_indirect and not self.quarantined:
            fb = self._fast_feedback()
            if fb is not None:
                return fb
            _log.debug("fast sync read failed; falling back to sync read")
            r = self.bus.sync_read(INDIRECT_DATA_1, FEEDBACK_SIZE, list(self.ids))
        else:
            ids = [i for i in self.ids if i not in self.quarantined]
            r = self._raw_read(ids)
        pos, vel, eff, hw, err, temp, volt, valid = _empty_columns(len(self.ids))
        unpack = _FEEDBACK_STRUCT.unpack
        index = self._index
        for sid, d in r.data.items():
            k = index[sid]
            p, v, c, h, t, u = unpack(d)
            pos[k], vel[k], eff[k], hw[k], temp[k], volt[k] = p, v, c, h, t, u
            valid[k] = True
        for sid, e in r.errors.items():
            err[index[sid]] = e
        self._count_failures(valid, r.missing)
        q = np.where(valid, self.map.to_radians(pos), np.nan)
        qd = np.where(valid, self.map.velocity_to_rad_s(vel), np.nan)
        return Feedback(self.bus.clock.now(), q, qd, eff, hw, err, temp, volt * VOLTAGE_UNIT_V, valid)
