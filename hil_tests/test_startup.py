"""Preflight, engage and recovery."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from drivers.control_table import HardwareErrorBits
from drivers.errors import PreflightError, SafetyError
from drivers.protocol import Instruction
from drivers.safety import LIMIT_TOLERANCE_RAD
from drivers.servo_map import ServoMap
from drivers.startup import arm_watchdog, engage, preflight, recover
from hil_tests.conftest import Rig, make_rig


def test_that_preflight_writes_only_settings_that_differ_and_then_nothing(rig: Rig) -> None:
    first = preflight(rig.group)
    assert {c.register for c in first.changes} == {"return_delay_time", "min_position_limit", "max_position_limit"}
    assert preflight(rig.group).changes == ()
    assert rig.mock.servo(13).get("max_position_limit") == rig.servo_map.by_id(13).limit_ticks[1]


def test_that_preflight_names_a_missing_servo(rig: Rig) -> None:
    rig.mock.faults.silence(9)
    with pytest.raises(PreflightError, match=r"\[9\]"):
        preflight(rig.group)


def test_that_preflight_names_a_wrong_model(servo_map: ServoMap) -> None:
    r = make_rig(servo_map)
    r.mock.servo(5).mem[0:2] = (1060).to_bytes(2, "little")
    with pytest.raises(PreflightError, match="id 5 .* is XL430-W250"):
        preflight(r.group)


def test_that_fast_read_is_not_used_with_old_firmware(servo_map: ServoMap) -> None:
    r = make_rig(servo_map, firmware_version=44)
    assert preflight(r.group).fast_read is False
    assert r.group.read_feedback().valid.all()


def test_that_engage_sets_goal_to_present_before_torque_on(servo_map: ServoMap) -> None:
    q0 = np.clip(np.full(20, 0.3), servo_map.lower_rad, servo_map.upper_rad)
    r = make_rig(servo_map, initial_rad=q0)
    preflight(r.group)
    engage(r.group, watchdog_s=0.1)
    for s in servo_map.servos:
        emu = r.mock.servo(s.id)
        assert emu.torque_on and emu.get("goal_position") == emu.get("present_position")
        assert emu.get("bus_watchdog") == 5


def test_that_recovery_reboots_a_shut_down_servo_and_holds_it(rig: Rig) -> None:
    preflight(rig.group)
    engage(rig.group)
    rig.mock.faults.hardware_error(6, HardwareErrorBits.OVERLOAD)
    rig.clock.sleep(0.01)
    rig.mock.advance()
    assert not rig.mock.servo(6).torque_on
    report = recover(rig.group, [6])
    assert report.ok and rig.mock.servo(6).torque_on and rig.mock.servo(6).hardware_error == 0


def test_that_recovery_gives_up_after_its_attempts_with_a_report(rig: Rig) -> None:
    preflight(rig.group)
    rig.mock.faults.silence(6)
    report = recover(rig.group, [6], attempts=2)
    assert report.failed == (6,) and report.attempts == 2 and "silent" in report.messages[-1]


def test_that_arm_watchdog_converts_seconds_to_20_ms_units(rig: Rig) -> None:
    assert arm_watchdog(rig.group, 0.25) == 12 and arm_watchdog(rig.group, 10.0) == 127


def test_that_preflight_turns_torque_off_before_writing_eeprom_that_differs(rig: Rig) -> None:
    for s in rig.servo_map.servos:
        rig.bus.write(s.id, 64, b"\x01")  # the servos were left holding
    report = preflight(rig.group)
    assert report.changes  # the emulator refuses EEPROM writes with torque on: they all landed
    for s in rig.servo_map.servos:
        lo, hi = s.limit_ticks
        emu = rig.mock.servo(s.id)
        assert (emu.get("min_position_limit"), emu.get("max_position_limit")) == (lo, hi)
        assert not emu.torque_on  # engage() turns it back on, goal = present first


def _fake_ftdi(tmp_path, value: str, *, writable: bool = True):
    dev = tmp_path / "dev" / "ttyUSB7"
    dev.parent.mkdir()
    dev.touch()
    sysfs = tmp_path / "sys"
    (sysfs / "ttyUSB7").mkdir(parents=True)
    timer = sysfs / "ttyUSB7" / "latency_timer"
    timer.write_text(value)
    if not writable:
        timer.chmod(0o444)
    return str(dev), sysfs, timer


def test_that_an_ftdi_latency_timer_of_16_ms_is_lowered_to_1(tmp_path) -> None:
    from drivers.port import ensure_low_latency

    device, sysfs, timer = _fake_ftdi(tmp_path, "16\n")
    result = ensure_low_latency(device, sysfs=sysfs)
    assert (result.before_ms, result.after_ms) == (16, 1) and timer.read_text().strip() == "1"
    assert "lowered 16 -> 1" in result.note


def test_that_an_unwritable_latency_timer_degrades_to_a_warning_with_a_hint(tmp_path, monkeypatch) -> None:
    from pathlib import Path

    from drivers.port import ensure_low_latency

    device, sysfs, timer = _fake_ftdi(tmp_path, "16\n")

    def refuse(self, *a, **k):
        raise PermissionError("read-only file system")

    monkeypatch.setattr(Path, "write_text", refuse)  # root ignores chmod; refuse the write itself
    result = ensure_low_latency(device, sysfs=sysfs)
    assert (result.before_ms, result.after_ms) == (16, 16)
    assert "caps the loop near 31 Hz" in result.note and "udev" in result.note


def test_that_an_adapter_without_latency_timer_is_reported_not_raised(tmp_path) -> None:
    from drivers.port import ensure_low_latency

    device = tmp_path / "ttyACM0"
    device.touch()
    result = ensure_low_latency(str(device), sysfs=tmp_path)
    assert result.path is None and "no latency timer" in result.note


def test_that_preflight_restores_position_mode_and_a_plain_drive_mode(rig: Rig) -> None:
    rig.bus.write(4, 11, b"\x01")  # velocity mode
    rig.bus.write(4, 10, b"\x05")  # reversed, time-based profile
    changes = {(c.servo_id, c.register, c.old, c.new) for c in preflight(rig.group).changes}
    assert {(4, "operating_mode", 1, 3), (4, "drive_mode", 5, 0)} <= changes
    assert rig.mock.servo(4).get("operating_mode") == 3 and rig.mock.servo(4).get("drive_mode") == 0


def test_that_preflight_clears_bus_watchdogs_tripped_by_a_dead_host(rig: Rig) -> None:
    preflight(rig.group)
    engage(rig.group, watchdog_s=0.1)
    rig.clock.advance(0.5)
    rig.mock.advance()  # the host died: every watchdog trips, goal writes are now refused
    assert all(rig.mock.servo(s.id).watchdog_tripped for s in rig.servo_map.servos)
    rig.group.torque(False)
    rig.mock.plant.set_position(1, 1.0)  # moved by hand while limp
    rig.mock.advance(rig.clock.now() + 0.01)
    preflight(rig.group)  # was: "write of 2 bytes at 100 refused: data range error"
    assert not any(rig.mock.servo(s.id).watchdog_tripped for s in rig.servo_map.servos)
    engage(rig.group, watchdog_s=0.1)
    s1 = rig.mock.servo(1)
    assert s1.torque_on and s1.get("goal_position") == s1.get("present_position")


def _torque_writes(r: Rig, start: int) -> list[tuple[int, int]]:
    """(servo id, value) of every Torque Enable write (plain or sync) in the log from ``start``."""
    out = []
    for p in r.mock.log[start:]:
        if p.instruction == Instruction.WRITE and struct.unpack_from("<H", p.params)[0] == 64:
            out.append((p.servo_id, p.params[2]))
        elif p.instruction == Instruction.SYNC_WRITE and struct.unpack_from("<HH", p.params) == (64, 1):
            out.extend((p.params[k], p.params[k + 1]) for k in range(4, len(p.params), 2))
    return out


def test_that_preflight_leaves_torque_on_when_the_indirect_map_is_already_right(rig: Rig) -> None:
    preflight(rig.group)
    engage(rig.group, watchdog_s=None)  # the robot is being held
    start = len(rig.mock.log)
    assert preflight(rig.group).changes == ()
    assert _torque_writes(rig, start) == []  # never went limp, not even briefly
    assert all(rig.mock.servo(s.id).torque_on for s in rig.servo_map.servos)


def test_that_preflight_rewrites_a_wrong_indirect_map_and_restores_torque(rig: Rig) -> None:
    preflight(rig.group)
    engage(rig.group, watchdog_s=None)
    rig.bus.write(7, 168, b"\x00\x00")  # Indirect Address 1 no longer points at Present Position
    start = len(rig.mock.log)
    preflight(rig.group)
    assert _torque_writes(rig, start) == [(7, 0), (7, 1)]
    assert all(rig.mock.servo(s.id).torque_on for s in rig.servo_map.servos)
    fb = rig.group.read_feedback()
    assert fb.valid.all() and np.allclose(fb.position_rad, 0.0, atol=1e-2)


def _pose_by_hand(r: Rig, servo_id: int, q_rad: float) -> None:
    """Torque off, the joint is moved to ``q_rad`` [rad] (servo-map frame) by hand."""
    r.mock.plant.set_position(servo_id, q_rad)
    r.mock.advance(r.clock.now() + 0.01)


def test_that_engage_refuses_a_joint_posed_outside_its_limits_and_leaves_torque_off(rig: Rig) -> None:
    preflight(rig.group)
    emu = rig.mock.servo(1)
    emu._set("goal_position", 2500)  # a goal left from an earlier session
    _pose_by_hand(rig, 1, rig.servo_map.upper_rad[0] + 0.3)  # past Max Position Limit
    with pytest.raises(SafetyError, match=r"r_sho_pitch \(id 1\) at 3\.09 rad.*-2\.79\.\.2\.79") as e:
        engage(rig.group, watchdog_s=0.1)
    assert "torque off" in e.value.hint and "servos.toml" in e.value.hint
    assert not any(rig.mock.servo(s.id).torque_on for s in rig.servo_map.servos)
    assert emu.get("goal_position") == 2500  # never moved towards it


def test_that_engage_holds_a_joint_just_past_its_limit_at_the_limit(rig: Rig) -> None:
    preflight(rig.group)
    _pose_by_hand(rig, 1, rig.servo_map.upper_rad[0] + LIMIT_TOLERANCE_RAD / 2)
    engage(rig.group, watchdog_s=None)
    emu = rig.mock.servo(1)
    assert emu.torque_on and emu.get("goal_position") == rig.servo_map.by_id(1).limit_ticks[1]


def test_that_engage_refuses_when_a_servo_did_not_take_goal_equal_present(rig: Rig) -> None:
    preflight(rig.group)
    rig.bus.write(4, 48, (2000).to_bytes(4, "little"))  # its Max Position Limit no longer the map's
    emu = rig.mock.servo(4)
    emu._set("goal_position", 1500)  # an old goal; goal = present (2048) is refused (Data Limit)
    with pytest.raises(SafetyError, match=r"l_sho_roll \(id 4\): goal 1500 ticks read back, 2048 written"):
        engage(rig.group, watchdog_s=0.1)
    assert not any(rig.mock.servo(s.id).torque_on for s in rig.servo_map.servos)
