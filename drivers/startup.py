"""Start-up, engage, stop and recovery sequences on a :class:`~drivers.group.ServoGroup`.

Preflight (:func:`preflight`): ping every expected ID and check its model number; read the
EEPROM settings we depend on (operating mode, return delay, position limits, drive mode) and
write only those that differ, with torque off; map the indirect feedback block; decide whether
Fast Sync Read can be used (every servo's firmware must support it).

Engage (:func:`engage`): refuse a joint outside its limits; goal = present position, read back;
then torque on, then arm the Bus Watchdog.

Recovery (:func:`recover`): a bounded number of attempts per servo: reboot, wait, ping,
re-apply the RAM settings, goal = present, torque on.
"""

from __future__ import annotations

import logging
import struct
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from drivers.bus import PingResult
from drivers.control_table import WATCHDOG_UNIT_S, HardwareErrorBits, model_for_number
from drivers.errors import CommunicationError, PreflightError, SafetyError, ServoStatusError
from drivers.group import BUS_WATCHDOG, GOAL_POSITION, TORQUE_ENABLE, ServoGroup
from drivers.safety import require_inside_limits
from drivers.servo_map import ServoSpec

__all__ = [
    "SettingChange",
    "PreflightReport",
    "RecoveryReport",
    "DRIVE_MODE_TIME_BASED",
    "preflight",
    "engage",
    "arm_watchdog",
    "disarm_watchdog",
    "recover",
    "desired_eeprom",
]

_log = logging.getLogger(__name__)

POSITION_MODE = 3
DRIVE_MODE_TIME_BASED = 0x04  # bit 2: time-based profile; we need velocity-based (cleared)
GOAL_READBACK_TOLERANCE_TICKS = 2  # [ticks] goal read back after goal = present, vs. the ticks written


@dataclass(frozen=True)
class SettingChange:
    """One EEPROM/RAM setting that preflight changed (or would change)."""

    servo_id: int
    register: str
    old: int
    new: int


@dataclass(frozen=True)
class PreflightReport:
    """What preflight found and did.

    Attributes:
        found: ping results by ID.
        changes: settings written because they differed.
        fast_read: Fast Sync Read is used.
        hardware_errors: ``{id: bits}`` found at start.
    """

    found: dict[int, PingResult]
    changes: tuple[SettingChange, ...]
    fast_read: bool
    hardware_errors: dict[int, int] = field(default_factory=dict)


@dataclass(frozen=True)
class RecoveryReport:
    """Outcome of :func:`recover`."""

    recovered: tuple[int, ...]
    failed: tuple[int, ...]
    attempts: int
    messages: tuple[str, ...]

    @property
    def ok(self) -> bool:
        return not self.failed


def desired_eeprom(spec: ServoSpec, return_delay_units: int) -> dict[str, int]:
    """EEPROM values the driver relies on for ``spec`` (register name -> raw value)."""
    lo, hi = spec.limit_ticks
    return {
        "operating_mode": POSITION_MODE,
        "return_delay_time": return_delay_units,
        "min_position_limit": lo,
        "max_position_limit": hi,
        "drive_mode": 0,  # direction is handled in software; velocity-based profile
    }


def preflight(group: ServoGroup, *, configure: bool = True, require_all: bool = True) -> PreflightReport:
    """Check and configure the bus before any motion (see module docstring).

    A Protocol 1.0 group is checked by :func:`drivers.startup1.preflight1` instead.

    Raises:
        PreflightError: a servo is missing, has the wrong model, or a setting cannot be written.
    """
    if group.protocol == 1.0:
        from drivers.startup1 import preflight1

        return preflight1(group, configure=configure, require_all=require_all)
    bus, smap = group.bus, group.map
    found = bus.scan(smap.ids)
    missing = [i for i in smap.ids if i not in found]
    if missing and require_all:
        raise PreflightError(
            f"servo(s) {missing} did not answer ({len(found)}/{len(smap)} found)",
            hint="check power and cabling; robot-rise servos scan --port PORT lists what answers")
    wrong = []
    for sid, r in found.items():
        spec = smap.by_id(sid)
        if r.model_number != spec.table.model_number:
            actual = model_for_number(r.model_number)
            wrong.append(f"id {sid} ({spec.joint}) is {actual.model if actual else r.model_number}, "
                         f"map says {spec.model}")
    if wrong:
        raise PreflightError("model mismatch: " + "; ".join(wrong), hint="fix servos.toml or the wiring")
    hw_errors: dict[int, int] = {}
    changes: list[SettingChange] = []
    rd_units = smap.bus.return_delay_units
    for sid in found:
        spec = smap.by_id(sid)
        table = spec.table
        hw = bus.read_value(sid, table["hardware_error_status"])
        if hw:
            hw_errors[sid] = hw
            _log.warning("servo %d: hardware error at start: %s", sid, HardwareErrorBits.describe(hw))
        want = desired_eeprom(spec, rd_units)
        diffs = []
        for name, value in want.items():
            old = bus.read_value(sid, table[name])
            if old != value:
                diffs.append(SettingChange(sid, name, old, value))
        if diffs and configure:
            bus.write_value(sid, table["torque_enable"], 0)
            for c in diffs:
                _log.info("servo %d: %s %d -> %d", sid, c.register, c.old, c.new)
                try:
                    bus.write_value(sid, table[c.register], c.new)
                except ServoStatusError as e:
                    raise PreflightError(f"cannot set {c.register} on servo {sid}: {e}",
                                         hint="is the value supported by this model?") from e
        changes.extend(diffs)
    if configure:
        apply_ram_settings(group, list(found))
    fast = all(r.firmware_version >= smap.by_id(i).table.fast_sync_read_min_firmware for i, r in found.items())
    group.fast_read = fast
    return PreflightReport(found, tuple(changes), fast, hw_errors)


def apply_ram_settings(group: ServoGroup, ids: list[int]) -> None:
    """(Re)write the RAM settings: Bus Watchdog cleared, indirect feedback map, status return
    level, Goal PWM.

    The Bus Watchdog is cleared first (0 written): after a host crash it has tripped (reads -1)
    and the servo refuses every goal write, Goal PWM included, with a Data Range Error until 0
    is written (e-manual, Bus Watchdog). :func:`engage` arms it again.

    The indirect map is written only where it differs (see :func:`_map_indirect_block`), so a
    servo that is holding and already mapped never goes limp.
    """
    bus = group.bus
    for sid in ids:
        table = group.map.by_id(sid).table
        bus.write_value(sid, table["bus_watchdog"], 0)
        if group.use_indirect:
            _map_indirect_block(group, sid)
        bus.write_value(sid, table["status_return_level"], 2)
        bus.write_value(sid, table["goal_pwm"], bus.read_value(sid, table["pwm_limit"]))


def _map_indirect_block(group: ServoGroup, sid: int) -> None:
    """Point servo ``sid``'s indirect addresses at the feedback block, unless they already do.

    They are written with torque off (as EEPROM-like protection may apply), and torque is
    restored if it was on; when the map already matches nothing is written.
    """
    bus = group.bus
    table = group.map.by_id(sid).table
    items = group.indirect_address_items()
    address, blob = items[0][0], b"".join(d for _, d in items)
    _, present = bus.read(sid, address, len(blob))
    if present == blob:
        return
    torque = bus.read_value(sid, table["torque_enable"])
    if torque:
        bus.write_value(sid, table["torque_enable"], 0)
    bus.write(sid, address, blob)
    if torque:
        bus.write_value(sid, table["torque_enable"], 1)


def engage(group: ServoGroup, *, watchdog_s: float | None = 0.1) -> None:
    """Goal = present position, torque on, then arm the Bus Watchdog (``None`` to skip).

    Torque comes on only when every servo provably holds where it is: no present position lies
    beyond its servo-map limits by more than ``LIMIT_TOLERANCE_RAD`` (a servo refuses a goal
    outside its Min/Max Position Limit, silently in a sync write, and would then drive to an
    old goal), a position within that tolerance is held at the limit, and the Goal Position
    read back matches what was written (:func:`_check_goals_taken`).

    Raises:
        CommunicationError: a servo did not report its position or goal.
        SafetyError: a joint is outside its limits, or a servo did not take goal = present;
            torque stays off.
    """
    fb = group.read_feedback()
    if not fb.valid.all():
        missing = [sid for sid, ok in zip(group.ids, fb.valid) if not ok]
        raise CommunicationError(f"no present position from servo(s) {missing}; not engaging")
    smap = group.map
    require_inside_limits(fb.position_rad, smap.lower_rad, smap.upper_rad, [sp.label for sp in smap.servos],
                          "not engaging")
    ticks = group.write_goals(np.clip(fb.position_rad, smap.lower_rad, smap.upper_rad))
    _check_goals_taken(group, ticks)
    group.torque(True)
    if watchdog_s is not None:
        arm_watchdog(group, watchdog_s)


def _check_goals_taken(group: ServoGroup, ticks: NDArray[np.int64]) -> None:
    """Read Goal Position back and refuse to engage where it differs from the ``ticks`` written
    (shape (n,), map order) by more than ``GOAL_READBACK_TOLERANCE_TICKS``: the sync write has
    no reply, and a servo that refused it (Data Limit Error: its own Min/Max Position Limit
    differs from the map; Data Range Error: a tripped Bus Watchdog) keeps an old goal."""
    read = group.read_each("goal_position")
    missing = [sid for sid in group.ids if sid not in read]
    if missing:
        raise CommunicationError(f"no goal position read back from servo(s) {missing}; not engaging")
    wrong = [f"{spec.label}: goal {read[spec.id]} ticks read back, {int(written)} written"
             for spec, written in zip(group.map.servos, ticks)
             if abs(read[spec.id] - int(written)) > GOAL_READBACK_TOLERANCE_TICKS]
    if wrong:
        raise SafetyError("goal = present did not take, not engaging: " + "; ".join(wrong),
                          hint="the servo refused the goal: run preflight (it writes the position limits "
                               "of servos.toml and clears a tripped Bus Watchdog), or reboot the servo")


def arm_watchdog(group: ServoGroup, timeout_s: float) -> int:
    """Arm every servo's Bus Watchdog at ``timeout_s`` [s] (20 ms units, 1..127); returns units
    (0, nothing sent, on a bus without one: Protocol 1.0)."""
    if not group.has_watchdog:
        return 0
    units = max(1, min(127, int(round(timeout_s / WATCHDOG_UNIT_S))))
    group.write_all(BUS_WATCHDOG, 1, 0)  # clear a tripped state first
    group.write_all(BUS_WATCHDOG, 1, units)
    return units


def disarm_watchdog(group: ServoGroup) -> None:
    if not group.has_watchdog:
        return
    group.write_all(BUS_WATCHDOG, 1, 0)


def recover(group: ServoGroup, ids: list[int], *, attempts: int = 2, boot_wait_s: float = 0.1,
            torque_on: bool = True) -> RecoveryReport:
    """Try to bring shut-down or silent servos back: reboot, re-apply RAM settings,
    goal = present, torque on. At most ``attempts`` tries per servo.

    Only ``ids`` are spoken to, for ``boot_wait_s`` and more: disarm the others' Bus Watchdog
    first (:func:`disarm_watchdog`) or it trips (the executor's stop does so).

    A Protocol 1.0 group (no reboot instruction) is recovered by :func:`drivers.startup1.recover1`."""
    if group.protocol == 1.0:
        from drivers.startup1 import recover1

        return recover1(group, ids, attempts=attempts, torque_on=torque_on)
    bus = group.bus
    recovered, failed, messages = [], [], []
    total = 0
    for sid in ids:
        table = group.map.by_id(sid).table
        ok = False
        for attempt in range(1, attempts + 1):
            total += 1
            try:
                bus.reboot(sid)
            except CommunicationError as e:
                messages.append(f"servo {sid}: reboot attempt {attempt} got no reply ({e})")
            bus.clock.sleep(boot_wait_s)
            if bus.ping(sid) is None:
                messages.append(f"servo {sid}: silent after reboot attempt {attempt}")
                continue
            try:
                hw = bus.read_value(sid, table["hardware_error_status"])
                if hw:
                    messages.append(f"servo {sid}: still {HardwareErrorBits.describe(hw)} after reboot")
                    continue
                apply_ram_settings(group, [sid])
                _, data = bus.read(sid, table["present_position"].address, 4)
                bus.write(sid, GOAL_POSITION, data)
                if torque_on:
                    bus.write(sid, TORQUE_ENABLE, b"\x01")
                group.quarantined.discard(sid)
                ok = True
                messages.append(f"servo {sid}: recovered on attempt {attempt} "
                                f"(holding {struct.unpack('<i', data)[0]} ticks)")
                break
            except CommunicationError as e:
                messages.append(f"servo {sid}: attempt {attempt} failed: {e}")
        (recovered if ok else failed).append(sid)
    return RecoveryReport(tuple(recovered), tuple(failed), total, tuple(messages))
