"""``ServoGroup1``: the servos of a Protocol 1.0 servo map on one bus, in joint units.

The same interface as :class:`drivers.group.ServoGroup` (what :mod:`drivers.startup`,
:mod:`drivers.executor` and the CLI call), for the 1.0 control tables of
:mod:`drivers.control_table1`, which share every address used here across AX, RX and MX:

    Torque Enable 24 | Goal Position 30 (2) | Moving Speed 32 (2) | Torque Limit 34 (2) |
    feedback block 36..43: Present Position (2), Speed (2), Load (2), Voltage (1), Temperature (1)

Per cycle: one SYNC_WRITE of every goal, then one BULK_READ of the feedback block of the MX
servos (list order) and one READ each of the AX/RX servos (they have no BULK_READ). A servo the
bulk read lost (a silent servo silences those listed after it) is read by itself, so one silent
servo costs one timeout, not the others' data; a servo without data for ``quarantine_after``
cycles is quarantined and re-pinged every ``reping_every`` cycles, as on 2.0.

Alarms: 1.0 has no Hardware Error Status register; the alarm bits of each servo's status error
byte (input voltage 0x01, overheating 0x04, overload 0x20: the same values as the 2.0 Hardware
Error Status bits) become ``Feedback.hardware_error``, so the safety layer judges them unchanged.

No Bus Watchdog (``has_watchdog`` False): the host stops the servos itself (see
:mod:`drivers.startup1`). The LIMP stop ramps Torque Limit (``ramp_register``) instead of Goal PWM.
"""

from __future__ import annotations

import logging
import struct
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from drivers.bus import GroupRead
from drivers.bus1 import DynamixelBus1
from drivers.control_table import ControlTable, Register, control_table
from drivers.control_table1 import decode_signed_magnitude
from drivers.errors import ControlTableError
from drivers.group import Feedback, _empty_columns, _ServoGroupBase
from drivers.protocol import BITS_PER_BYTE
from drivers.protocol1 import ErrorBits1
from drivers.servo_map import ServoMap

__all__ = ["FEEDBACK_ADDRESS_1", "FEEDBACK_SIZE_1", "ServoGroup1"]

_log = logging.getLogger(__name__)

_LAYOUT: ControlTable = control_table("MX-28", 1.0)  # every 1.0 table shares these addresses
_FEEDBACK_REGISTERS = ("present_position", "present_speed", "present_load", "present_voltage",
                       "present_temperature")
FEEDBACK_ADDRESS_1 = _LAYOUT["present_position"].address  # 36
FEEDBACK_SIZE_1 = sum(_LAYOUT[n].size for n in _FEEDBACK_REGISTERS)  # 8 bytes: 36..43
_FEEDBACK_STRUCT = struct.Struct("<HHHBB")
GOAL_POSITION_1 = _LAYOUT["goal_position"]
TORQUE_ENABLE_1 = _LAYOUT["torque_enable"]
TORQUE_LIMIT_1 = _LAYOUT["torque_limit"]
_USED_REGISTERS = tuple(_LAYOUT[n] for n in (*_FEEDBACK_REGISTERS, "goal_position", "torque_enable",
                                              "torque_limit", "moving_speed"))
_GOAL_BLOCK = np.dtype([("id", "u1"), ("ticks", "<u2")])


def _check_layout(table: ControlTable) -> None:
    for reg in _USED_REGISTERS:
        other = table.at(reg.address)
        if other is None or other.size != reg.size or table.protocol != 1.0:
            raise ControlTableError(f"{table.model} has no {reg.size}-byte register at {reg.address} ({reg.name})",
                                    hint="a Protocol 1.0 servo group needs the AX/RX/MX (1.0) layout on every servo")


class ServoGroup1(_ServoGroupBase):
    """The servos of a Protocol 1.0 ``servo_map`` on ``bus``, spoken to in radians.

    Args:
        bus: the :class:`~drivers.bus1.DynamixelBus1`.
        servo_map: which IDs, joints, directions and limits (``[bus] protocol = 1.0``).
        quarantine_after: consecutive missing reads before a servo is quarantined.
        reping_every: cycles between re-pings of quarantined servos.
        fast_read, use_indirect: accepted for the 2.0 group's callers; always False on 1.0.
    """

    bus: DynamixelBus1  # its read_each_servo and bulk_read are used here
    protocol = 1.0
    has_watchdog = False  # 1.0 firmware has no Bus Watchdog
    pipelinable = False
    ramp_register: Register = TORQUE_LIMIT_1  # what a LIMP stop ramps to 0
    ramp_limit_register = "torque_limit"  # where the ramp starts, per servo

    def __init__(self, bus: DynamixelBus1, servo_map: ServoMap, *, fast_read: bool = False,
                 use_indirect: bool = False, quarantine_after: int = 2, reping_every: int = 10) -> None:
        super().__init__(bus, servo_map, check_layout=_check_layout, quarantine_after=quarantine_after,
                         reping_every=reping_every)
        self.fast_read = False
        self.use_indirect = False
        self.bulk_ids = tuple(s.id for s in servo_map.servos if s.table.bulk_read)
        self.single_ids = tuple(s.id for s in servo_map.servos if not s.table.bulk_read)
        tables = [s.table for s in servo_map.servos]
        self._max_ticks = np.array([t.max_ticks for t in tables], dtype=np.int64)
        d = np.array([s.direction for s in servo_map.servos], dtype=float)
        self._velocity_scale = d * np.array([t.velocity_unit_rad_s for t in tables])
        self._goal_header = bytes((GOAL_POSITION_1.address, GOAL_POSITION_1.size))
        self._goal_block = np.zeros(len(self.ids), dtype=_GOAL_BLOCK)
        self._goal_block["id"] = np.array(self.ids, dtype=np.uint8)

    def cycle_wire_time_s(self) -> float:
        """Wire time of one cycle [s]: goal SYNC_WRITE, the MX servos' BULK_READ and each AX/RX
        servo's READ, with each servo's return delay. ``1 / this`` is the highest rate the bus
        allows."""
        n, n_bulk, n_single = len(self.ids), len(self.bulk_ids), len(self.single_ids)
        write_b = 8 + 3 * n
        reply_b = n * (6 + FEEDBACK_SIZE_1)
        request_b = (7 + 3 * n_bulk if n_bulk else 0) + 8 * n_single
        delays = n * self.map.bus.return_delay_time_us * 1e-6
        return (write_b + request_b + reply_b) * BITS_PER_BYTE / self.bus.baud_rate + delays

    # ---- writes ---------------------------------------------------------------------------
    def write_goals(self, q_rad: NDArray[np.float64], *, skip: Sequence[int] = (),
                    defer: bool = False) -> NDArray[np.int64]:
        """SYNC_WRITE goal positions for joint angles ``q_rad`` [rad], shape (n,); quarantined
        servos and ``skip`` IDs are left out. Returns the ticks sent, shape (n,)."""
        ticks = np.clip(self.map.to_ticks(q_rad), 0, self._max_ticks)
        if not self.quarantined and not skip:
            block = self._goal_block
            block["ticks"] = ticks
            self.bus.sync_write_params(self._goal_header + block.tobytes(), defer=defer)
            return ticks
        data = {sid: int(t).to_bytes(2, "little") for sid, t in zip(self.ids, ticks)
                if sid not in self.quarantined and sid not in skip}
        self.bus.sync_write(GOAL_POSITION_1.address, GOAL_POSITION_1.size, data, defer=defer)
        return ticks

    def torque(self, on: bool, ids: Sequence[int] | None = None, *, quarantined_too: bool = False) -> None:
        """Torque Enable on all (``ids`` None) or on ``ids`` only (empty: none) by SYNC_WRITE."""
        self.write_all(TORQUE_ENABLE_1.address, TORQUE_ENABLE_1.size, int(on), ids, quarantined_too=quarantined_too)

    def read_each(self, name: str) -> dict[int, int]:
        """One READ of register ``name`` from every active servo: ID -> raw value (servos that
        did not answer, or whose model lacks the register, are absent)."""
        items = []
        regs = {}
        for spec in self.map.servos:
            if spec.id in self.quarantined or not spec.table.has(name):
                continue
            reg = spec.table[name]
            regs[spec.id] = reg
            items.append((spec.id, reg.address, reg.size))
        r = self.bus.read_each_servo(items)
        return {sid: regs[sid].decode(d) for sid, d in r.data.items()}

    # ---- reads ----------------------------------------------------------------------------
    def _raw_read(self) -> GroupRead:
        active_bulk = [(sid, FEEDBACK_ADDRESS_1, FEEDBACK_SIZE_1) for sid in self.bulk_ids if sid not in self.quarantined]
        active_single = [(sid, FEEDBACK_ADDRESS_1, FEEDBACK_SIZE_1) for sid in self.single_ids
                         if sid not in self.quarantined]
        r = self.bus.bulk_read(active_bulk) if active_bulk else GroupRead({}, {}, ())
        if not active_single:
            return r
        r2 = self.bus.read_each_servo(active_single)
        return GroupRead({**r.data, **r2.data}, {**r.errors, **r2.errors}, r.missing + r2.missing)

    def read_feedback(self) -> Feedback:
        """One group read of the feedback block of every active servo, in joint units."""
        self._start_read()
        r = self._raw_read()
        pos, vel, eff, hw, err, temp, volt, valid = _empty_columns(len(self.ids))
        unpack = _FEEDBACK_STRUCT.unpack
        signed = decode_signed_magnitude
        index = self._index
        for sid, d in r.data.items():
            k = index[sid]
            p, v, load, u, t = unpack(d)
            pos[k], vel[k], eff[k], volt[k], temp[k] = p, signed(v), signed(load), u, t
            valid[k] = True
        for sid, e in r.errors.items():
            k = index[sid]
            err[k] = e
            hw[k] = e & ErrorBits1.HARDWARE
        self._count_failures(valid, r.missing)
        q = np.where(valid, self.map.to_radians(pos), np.nan)
        qd = np.where(valid, vel * self._velocity_scale, np.nan)
        return Feedback(self.bus.clock.now(), q, qd, eff, hw, err, temp, volt * 0.1, valid)
