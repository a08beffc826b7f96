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
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from drivers.bus import DynamixelBus, PingResult
from drivers.control_table import WATCHDOG_UNIT_S, ControlTable, HardwareErrorBits, model_for_number
from drivers.errors import CommunicationError, PreflightError, SafetyError, ServoStatusError
from drivers.group import BUS_WATCHDOG, ServoGroup
from drivers.safety import require_inside_limits
from drivers.servo_map import ServoSpec

if TYPE_CHECKING:
    from drivers.group1 import ServoGroup1

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
    found = _find_servos(group, require_all=require_all)
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
        diffs = _setting_changes(bus, sid, table, desired_eeprom(spec, rd_units))
        if diffs and configure:
            _write_changes(bus, sid, table, diffs)
        changes.extend(diffs)
    if configure:
        apply_ram_settings(group, list(found))
    fast = all(r.firmware_version >= smap.by_id(i).table.fast_sync_read_min_firmware for i, r in found.items())
    group.fast_read = fast
    return PreflightReport(found, tuple(changes), fast, hw_errors)


def _find_servos(group: ServoGroup | ServoGroup1, *, require_all: bool) -> dict[int, PingResult]:
    """Ping every ID of the group's map: the answers by ID, each of the model the map names.

    Raises:
        PreflightError: a servo did not answer (with ``require_all``) or is another model.
    """
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
            actual = model_for_number(r.model_number, group.protocol)
            wrong.append(f"id {sid} ({spec.joint}) is {actual.model if actual else r.model_number}, "
                         f"map says {spec.model}")
    if wrong:
        raise PreflightError("model mismatch: " + "; ".join(wrong), hint="fix servos.toml or the wiring")
    return found


def _setting_changes(bus: DynamixelBus, sid: int, table: ControlTable, want: Mapping[str, int], *,
                     present: Mapping[str, int] | None = None) -> list[SettingChange]:
    """The settings of servo ``sid`` that differ from ``want`` (register name -> raw value);
    values in ``present`` were read already and are not read again."""
    present = present or {}
    diffs = []
    for name, value in want.items():
        old = present[name] if name in present else bus.read_value(sid, table[name])
        if old != value:
            diffs.append(SettingChange(sid, name, old, value))
    return diffs


def _write_changes(bus: DynamixelBus, sid: int, table: ControlTable, diffs: list[SettingChange]) -> None:
    """Write ``diffs`` to servo ``sid``, torque off first.

    Raises:
        PreflightError: the servo refused a value.
    """
    bus.write_value(sid, table["torque_enable"], 0)
    for c in diffs:
        _log.info("servo %d: %s %d -> %d", sid, c.register, c.old, c.new)
        try:
            bus.write_value(sid, table[c.register], c.new)
        except ServoStatusError as e:
            raise PreflightError(f"cannot set {c.register} on servo {sid}: {e}",
                                 hint="is the value supported by this model?") from e


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

    def attempt_once(sid: int, attempt: int, messages: list[str]) -> bool:
        table = group.map.by_id(sid).table
        try:
            bus.reboot(sid)
        except CommunicationError as e:
            messages.append(f"servo {sid}: reboot attempt {attempt} got no reply ({e})")
        bus.clock.sleep(boot_wait_s)
        if bus.ping(sid) is None:
            messages.append(f"servo {sid}: silent after reboot attempt {attempt}")
            return False
        try:
            hw = bus.read_value(sid, table["hardware_error_status"])
        except CommunicationError as e:
            messages.append(f"servo {sid}: attempt {attempt} failed: {e}")
            return False
        if hw:
            messages.append(f"servo {sid}: still {HardwareErrorBits.describe(hw)} after reboot")
            return False
        return _hold_again(group, sid, table, attempt, messages, apply_ram=apply_ram_settings, torque_on=torque_on)

    return _recover_each(ids, attempts, attempt_once)


def _recover_each(ids: list[int], attempts: int, attempt_once: Callable[[int, int, list[str]], bool]) -> RecoveryReport:
    """At most ``attempts`` calls of ``attempt_once(sid, attempt, messages)`` per servo of ``ids``,
    until one returns True (recovered); each adds what it found to ``messages``."""
    recovered, failed, messages = [], [], []
    total = 0
    for sid in ids:
        ok = False
        for attempt in range(1, attempts + 1):
            total += 1
            if attempt_once(sid, attempt, messages):
                ok = True
                break
        (recovered if ok else failed).append(sid)
    return RecoveryReport(tuple(recovered), tuple(failed), total, tuple(messages))


def _hold_again(group: ServoGroup | ServoGroup1, sid: int, table: ControlTable, attempt: int, messages: list[str], *,
                apply_ram: Callable[..., None], torque_on: bool) -> bool:
    """The end of a recovery attempt on a servo that answers: its RAM settings again
    (``apply_ram(group, [sid])``), goal = present position, torque on if ``torque_on``, out of
    quarantine. True if it holds; a communication error ends the attempt (False). Either way
    ``messages`` says so."""
    bus = group.bus
    try:
        apply_ram(group, [sid])
        present = table["present_position"]
        _, data = bus.read(sid, present.address, present.size)
        bus.write(sid, table["goal_position"].address, data)
        if torque_on:
            bus.write_value(sid, table["torque_enable"], 1)
        group.quarantined.discard(sid)
        messages.append(f"servo {sid}: recovered on attempt {attempt} (holding {present.decode(data)} ticks)")
        return True
    except CommunicationError as e:
        messages.append(f"servo {sid}: attempt {attempt} failed: {e}")
        return False
