"""Start-up, recovery and the host's own stop on a Protocol 1.0 bus (:class:`~drivers.group1.ServoGroup1`).

:func:`drivers.startup.preflight`, :func:`~drivers.startup.recover`, ``arm_watchdog`` and
``disarm_watchdog`` dispatch here for a 1.0 group; :func:`drivers.startup.engage` works as it
is (goal = present read back, then torque on; no watchdog to arm).

Preflight (:func:`preflight1`): ping every expected ID and check its model number; check and
write, with torque off, the EEPROM the driver relies on (Return Delay Time, Status Return
Level 2, CW/CCW Angle Limits = the servo map's limits, which also keeps the servo out of wheel
mode, Alarm Shutdown including overheating and overload); then the RAM settings
(:func:`apply_ram_settings1`): Torque Limit = Max Torque (the cap: an earlier LIMP stop or alarm
shutdown left it lower), Moving Speed 0 (no speed cap: the executor's step limit governs), and
the compliance margins / slopes (AX, RX) or P, I, D gains (MX) at the model's defaults (the
values the catalog's servo model and so the proof assume). The alarm bits each servo reports
are read and returned as ``hardware_errors``.

What the host can and cannot do without a Bus Watchdog (1.0 firmware has none: a servo keeps
its last goal, torque on, for as long as it has power):

- Ctrl-C, SIGTERM, SIGHUP (a closed terminal, ``kill PID``): :func:`host_stop_guard` turns them
  into the executor's controlled stop (KeyboardInterrupt), and an exception that escapes the
  guarded block turns torque off on its way out.
- A fault in the loop (tracking, alarms, a silent servo, a port error that still lets bytes
  out): the executor's stop policy, as on 2.0.
- Not possible: SIGKILL, a host crash or power loss, the USB adapter unplugged, the bus cable
  cut. Nothing more reaches the servos; they hold the last goal. What remains is the servos'
  own Alarm Shutdown (overload, overheating: Torque Limit 0, the shaft goes free), which
  preflight makes sure is on, and the Torque Limit cap.
"""

from __future__ import annotations

import contextlib
import logging
import signal
import threading
from collections.abc import Iterator
from typing import TYPE_CHECKING

from drivers.errors import CommunicationError
from drivers.protocol1 import ErrorBits1
from drivers.servo_map import ServoSpec
from drivers.startup import (
    PreflightReport,
    RecoveryReport,
    SettingChange,
    _find_servos,
    _hold_again,
    _recover_each,
    _setting_changes,
    _write_changes,
)

if TYPE_CHECKING:
    from drivers.group1 import ServoGroup1

__all__ = [
    "REQUIRED_SHUTDOWN_BITS",
    "desired_eeprom1",
    "desired_ram1",
    "preflight1",
    "apply_ram_settings1",
    "recover1",
    "host_stop_guard",
]

_log = logging.getLogger(__name__)

# Alarm Shutdown must include these (the factory default 36 = overheating + overload)
REQUIRED_SHUTDOWN_BITS = ErrorBits1.OVERHEATING | ErrorBits1.OVERLOAD
_STATUS_RETURN_ALL = 2


def desired_eeprom1(spec: ServoSpec, return_delay_units: int, present: dict[str, int]) -> dict[str, int]:
    """EEPROM values the driver relies on for ``spec`` (register name -> raw value); ``present``
    holds the servo's current Alarm Shutdown (bits are only ever added to it)."""
    lo, hi = spec.limit_ticks
    return {
        "return_delay_time": return_delay_units,
        "status_return_level": _STATUS_RETURN_ALL,
        "cw_angle_limit": lo,
        "ccw_angle_limit": hi,
        "alarm_shutdown": present.get("alarm_shutdown", 0) | REQUIRED_SHUTDOWN_BITS,
    }


def desired_ram1(spec: ServoSpec, max_torque: int) -> dict[str, int]:
    """RAM values written at every preflight and recovery (see the module docstring)."""
    table = spec.table
    out = {"torque_limit": max_torque, "moving_speed": 0}
    for name in ("p_gain", "i_gain", "d_gain", "cw_compliance_margin", "ccw_compliance_margin",
                 "cw_compliance_slope", "ccw_compliance_slope"):
        if table.has(name):
            out[name] = int(table.defaults.get(name, 0))
    return out


def preflight1(group: "ServoGroup1", *, configure: bool = True, require_all: bool = True) -> PreflightReport:
    """Check and configure a Protocol 1.0 bus before any motion (see the module docstring).

    Raises:
        PreflightError: a servo is missing, has the wrong model, or a setting cannot be written.
    """
    bus, smap = group.bus, group.map
    found = _find_servos(group, require_all=require_all)
    hw_errors: dict[int, int] = {}
    changes: list[SettingChange] = []
    rd_units = smap.bus.return_delay_units
    for sid, r in found.items():
        spec = smap.by_id(sid)
        table = spec.table
        if r.error & ErrorBits1.HARDWARE:
            hw_errors[sid] = r.error & ErrorBits1.HARDWARE
            _log.warning("servo %d: alarm at start: %s", sid, ErrorBits1.describe(r.error))
        present = {"alarm_shutdown": bus.read_value(sid, table["alarm_shutdown"])}
        diffs = _setting_changes(bus, sid, table, desired_eeprom1(spec, rd_units, present), present=present)
        if diffs and configure:
            _write_changes(bus, sid, table, diffs)
        changes.extend(diffs)
    if configure:
        apply_ram_settings1(group, list(found))
    group.fast_read = False
    return PreflightReport(found, tuple(changes), False, hw_errors)


def apply_ram_settings1(group: "ServoGroup1", ids: list[int]) -> None:
    """(Re)write the RAM settings of ``ids``: Torque Limit = Max Torque, Moving Speed 0, gains or
    compliance at the model's defaults. Written only where they differ (one READ of the span)."""
    bus = group.bus
    for sid in ids:
        spec = group.map.by_id(sid)
        table = spec.table
        max_torque = bus.read_value(sid, table["max_torque"])
        for name, value in desired_ram1(spec, max_torque).items():
            if bus.read_value(sid, table[name]) != value:
                bus.write_value(sid, table[name], value)


def recover1(group: "ServoGroup1", ids: list[int], *, attempts: int = 2, torque_on: bool = True) -> RecoveryReport:
    """Bring servos back after an alarm shutdown (Torque Limit 0) or a silence, at most
    ``attempts`` tries each: ping, the alarm bits read (input voltage or overheating still
    present: not recovered, the cause must go first), Torque Limit = Max Torque and the other
    RAM settings written again (this also clears a latched overload), goal = present, torque on.
    There is no reboot on 1.0: a servo that stays silent needs its power cycled."""
    bus = group.bus

    def attempt_once(sid: int, attempt: int, messages: list[str]) -> bool:
        table = group.map.by_id(sid).table
        ping = bus.ping(sid)
        if ping is None:
            messages.append(f"servo {sid}: silent (attempt {attempt}; Protocol 1.0 has no reboot: "
                            "power-cycle it)")
            return False
        live = ping.error & (ErrorBits1.INPUT_VOLTAGE | ErrorBits1.OVERHEATING)
        if live:
            messages.append(f"servo {sid}: still {ErrorBits1.describe(live)}")
            return False
        return _hold_again(group, sid, table, attempt, messages, apply_ram=apply_ram_settings1, torque_on=torque_on)

    return _recover_each(ids, attempts, attempt_once)


class _Terminated(KeyboardInterrupt):
    """SIGTERM / SIGHUP, delivered as a KeyboardInterrupt so that the executor's controlled stop runs."""


@contextlib.contextmanager
def host_stop_guard(group: "ServoGroup1 | object") -> Iterator[None]:
    """While streaming to a bus without a Bus Watchdog: SIGTERM and SIGHUP become a
    KeyboardInterrupt (the executor stops by its policy, as on Ctrl-C), and an exception that
    leaves the block (the host's own error, a second interrupt) turns every servo's torque off
    on the way out. A no-op for a group with a watchdog, or off the main thread (signals cannot
    be caught there)."""
    if getattr(group, "has_watchdog", True) or threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum: int, frame: object) -> None:
        raise _Terminated(f"signal {signum}")

    previous = {sig: signal.signal(sig, interrupt) for sig in (signal.SIGTERM, signal.SIGHUP)}
    try:
        yield
    except BaseException:
        _log.error("leaving the bus without a controlled stop: torque off on every servo")
        try:
            group.torque(False, quarantined_too=True)  # type: ignore[attr-defined]
        except CommunicationError as e:
            _log.error("torque off failed: %s", e)
        raise
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
