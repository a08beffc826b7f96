"""The Protocol 1.0 bus end to end on the emulator: the servo map, preflight, partial reads,
faults, alarms, the executor's stops, dynamixel_sdk's own 1.0 packet handler, the CLI."""

from __future__ import annotations

import re
import shutil
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from dynamixel_sdk import COMM_SUCCESS, GroupBulkRead, GroupSyncWrite, PacketHandler, PortHandler

import drivers.mockbus as mb
from drivers.clock import FakeClock
from drivers.control_table import HardwareErrorBits, control_table
from drivers.errors import ServoMapError, ServoStatusError
from drivers.executor import Executor, ExecutorConfig
from drivers.group1 import ServoGroup1
from drivers.mockbus.pty_server import PtyServer
from drivers.protocol1 import ErrorBits1
from drivers.safety import FaultKind, SafetyLimits, StopPolicy
from drivers.servo_map import ServoMap, load_servo_map, parse_servo_map, with_protocol
from drivers.session import Connection, connect, mock_bus_for, mock_url_for
from drivers.startup import engage, preflight
from drivers.startup1 import host_stop_guard
from hil_tests.conftest import pty_served_by_thread

REPO = Path(__file__).resolve().parents[1]
POPPY_P1 = REPO.parent / "shared" / "robots" / "poppy" / "poppy_servos_p1.toml"
OP3 = REPO / "configs" / "robots" / "op3"


@pytest.fixture(scope="module")
def poppy() -> ServoMap:
    if not POPPY_P1.exists():
        pytest.skip(f"{POPPY_P1} not present")
    return load_servo_map(POPPY_P1)


@pytest.fixture
def rig(poppy: ServoMap) -> Iterator[tuple[Connection, mb.MockBus1]]:
    clock = FakeClock()
    url = mock_url_for(poppy, clock=clock)
    emu = mb.attached(url.removeprefix("dxlsim://"))
    assert isinstance(emu, mb.MockBus1)
    with connect(poppy, url) as conn:
        yield conn, emu
    mb.detach(url.removeprefix("dxlsim://"))


def _limits(smap: ServoMap) -> SafetyLimits:
    return SafetyLimits(smap.lower_rad, smap.upper_rad)


def _wave(fb_q: np.ndarray, smap: ServoMap, amplitude: float = 0.15, seconds: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, seconds, 11)
    q = fb_q[None, :] + amplitude * np.sin(np.pi * t / seconds)[:, None]
    return t, np.clip(q, smap.lower_rad, smap.upper_rad)


# ---- the servo map ------------------------------------------------------------------------
def test_that_the_poppy_1_0_map_is_read_with_its_ax_18a_head(poppy: ServoMap) -> None:
    assert poppy.protocol == 1.0 and len(poppy) == 25
    head = poppy.by_joint("head_z")
    assert head.table.model == "AX-18A" and head.table.center_ticks == 512 and head.table.max_ticks == 1023
    assert poppy.by_joint("r_hip_y").table.model == "MX-64(1.0)"  # MX-64 on a 1.0 bus: the 1.0 firmware
    ticks = poppy.to_ticks(np.zeros(len(poppy)))
    assert ticks[poppy.joint_names.index("head_z")] == 512 and ticks[0] == 2048
    # AX: 1023 ticks over 300 deg
    assert head.to_ticks(np.radians(30.0)) == 512 + 102 and head.to_ticks(np.radians(-150.0)) in (0, 1)
    assert poppy.to_radians(poppy.to_ticks(poppy.lower_rad)) == pytest.approx(poppy.lower_rad, abs=0.006)


def test_that_a_1_0_model_on_a_2_0_bus_and_an_unknown_protocol_are_refused_with_the_fix() -> None:
    row = {"id": 1, "joint": "a", "model": "AX-12A", "min": -1.0, "max": 1.0}
    with pytest.raises(ServoMapError, match="speaks Protocol 1.0") as e:
        parse_servo_map({"format": "robot-rise/servos@1", "bus": {"protocol": 2.0}, "servo": [row]})
    assert "protocol = 1.0" in e.value.hint
    with pytest.raises(ServoMapError, match="not a Dynamixel protocol"):
        parse_servo_map({"format": "robot-rise/servos@1", "bus": {"protocol": 3.0}, "servo": [row]})
    x_row = {**row, "model": "XM430-W350"}
    with pytest.raises(ServoMapError, match="Protocol 2.0 only"):
        parse_servo_map({"format": "robot-rise/servos@1", "bus": {"protocol": 1.0}, "servo": [x_row]})
    wide = {**row, "min": -2.8, "max": 2.8}  # beyond an AX's 300 deg
    with pytest.raises(ServoMapError, match="outside 0..1023"):
        parse_servo_map({"format": "robot-rise/servos@1", "bus": {"protocol": 1.0}, "servo": [wide]})


def test_that_every_1_0_table_has_its_model_number_and_source() -> None:
    numbers = {m: control_table(m, 1.0).model_number for m in
               ("AX-12A", "AX-18A", "RX-28", "RX-64", "MX-28", "MX-64", "MX-106")}
    assert numbers == {"AX-12A": 12, "AX-18A": 18, "RX-28": 28, "RX-64": 64, "MX-28": 29, "MX-64": 310, "MX-106": 320}
    for m in numbers:
        t = control_table(m, 1.0)
        assert t.source.startswith("https://emanual.robotis.com/") and t.protocol == 1.0
        assert t["goal_position"].address == 30 and t["present_position"].address == 36
        assert t.has("p_gain") == t.bulk_read == m.startswith("MX")
        assert t.has("cw_compliance_slope") != m.startswith("MX")


# ---- preflight, reads, faults -------------------------------------------------------------
def test_that_preflight_finds_every_servo_writes_the_limits_once_and_engage_holds(rig) -> None:
    conn, emu = rig
    assert isinstance(conn.group, ServoGroup1)
    pre = preflight(conn.group)
    assert len(pre.found) == 25 and not pre.fast_read and not pre.hardware_errors
    assert {c.register for c in pre.changes} >= {"cw_angle_limit", "ccw_angle_limit"}
    head = conn.group.map.by_joint("head_y")
    assert emu.servo(head.id).get("cw_angle_limit") == head.limit_ticks[0]
    assert preflight(conn.group).changes == ()  # nothing left to change
    engage(conn.group, watchdog_s=0.1)  # no watchdog on 1.0: nothing armed, torque on
    assert all(s.torque_on for s in emu.servos.values())


def test_that_a_silent_servo_costs_only_its_own_data_and_is_quarantined_then_readmitted(rig) -> None:
    conn, emu = rig
    g = conn.group
    preflight(g)
    middle = g.bulk_ids[5]  # silences every MX listed after it in the BULK_READ
    emu.faults.silence(middle)
    for _ in range(g.quarantine_after):
        fb = g.read_feedback()
        k = g.ids.index(middle)
        assert not fb.valid[k] and fb.valid.sum() == len(g.ids) - 1
        assert np.isnan(fb.position_rad[k])
    assert middle in g.quarantined
    emu.faults.restore(middle)
    for _ in range(g.reping_every):
        g.read_feedback()
    assert middle not in g.quarantined and g.read_feedback().valid.all()


def test_that_corrupt_and_dropped_replies_never_raise_and_only_cost_their_servo(rig) -> None:
    conn, emu = rig
    g = conn.group
    preflight(g)
    g.quarantine_after = 10**6
    emu.faults.corrupt_probability = 0.05
    emu.faults.drop_probability = 0.05
    valid = 0
    for _ in range(40):
        fb = g.read_feedback()
        valid += int(fb.valid.sum())
        assert np.all(np.isfinite(fb.position_rad[fb.valid]))
    assert valid > 0.8 * 40 * len(g.ids)
    assert conn.bus.stats.corrupt_replies + conn.bus.stats.timeouts > 0


def test_that_a_refused_goal_raises_with_the_angle_limit_bit(rig) -> None:
    conn, _ = rig
    preflight(conn.group)
    spec = conn.group.map.by_joint("r_knee_y")
    with pytest.raises(ServoStatusError, match="angle limit") as e:
        conn.bus.write_value(spec.id, spec.table["goal_position"], spec.limit_ticks[1] + 50)
    assert e.value.error & ErrorBits1.ANGLE_LIMIT


# ---- the executor on 1.0 ------------------------------------------------------------------
def test_that_a_trajectory_streams_to_the_1_0_bus_and_ends_holding(rig, poppy: ServoMap) -> None:
    conn, emu = rig
    preflight(conn.group)
    engage(conn.group)
    q0 = conn.group.read_feedback().position_rad
    t, q = _wave(q0, poppy)
    rep = Executor(conn.group, _limits(poppy), ExecutorConfig()).run(poppy.joint_names, t, q)
    assert rep.completed and not rep.faults and rep.stats.cycles >= 50
    assert rep.max_tracking_error_rad < 0.1
    assert all(s.torque_on for s in emu.servos.values())  # HOLD: torque stays on


def test_that_an_overload_alarm_stops_the_run_and_recovery_gives_the_torque_back(rig, poppy: ServoMap) -> None:
    conn, emu = rig
    g = conn.group
    preflight(g)
    engage(g)
    sid = poppy.by_joint("l_knee_y").id
    emu.faults.at(emu.clock.now() + 0.2, lambda bus: bus.faults.hardware_error(sid, HardwareErrorBits.OVERLOAD))
    t, q = _wave(g.read_feedback().position_rad, poppy, seconds=1.0)
    rep = Executor(g, _limits(poppy), ExecutorConfig()).run(poppy.joint_names, t, q)
    assert not rep.completed
    assert any(f.kind is FaultKind.HARDWARE and f.index == g.ids.index(sid) for f in rep.faults)
    assert emu.servo(sid).shutdowns == 1  # Alarm Shutdown took the torque (Torque Limit 0)
    assert rep.recovery is not None and rep.recovery.recovered == (sid,)
    assert emu.servo(sid).get("torque_limit") == 1023 and emu.servo(sid).hardware_error == 0


def test_that_a_limp_stop_ramps_the_torque_limit_down_and_ends_with_torque_off(rig, poppy: ServoMap) -> None:
    conn, emu = rig
    preflight(conn.group)
    engage(conn.group)
    seen: list[int] = []
    sid = poppy.ids[0]
    emu.packet_listeners.append(lambda _t, p: seen.append(p.params[2 + 3 * 0 + 1] | (p.params[2 + 3 * 0 + 2] << 8))
                                if p.instruction == 0x83 and p.params[0] == 34 and p.params[2] == sid else None)
    t, q = _wave(conn.group.read_feedback().position_rad, poppy, seconds=0.3)
    rep = Executor(conn.group, _limits(poppy), ExecutorConfig(stop_policy=StopPolicy.LIMP, limp_s=0.2)).run(
        poppy.joint_names, t, q)
    assert rep.completed
    assert seen and seen == sorted(seen, reverse=True) and seen[-1] == 0 and seen[0] <= 1023
    assert not any(s.torque_on for s in emu.servos.values())


def test_that_an_exception_leaving_the_host_guard_turns_the_torque_off(rig) -> None:
    conn, emu = rig
    preflight(conn.group)
    engage(conn.group)
    with pytest.raises(RuntimeError):
        with host_stop_guard(conn.group):
            raise RuntimeError("host bug")
    assert not any(s.torque_on for s in emu.servos.values())


# ---- dynamixel_sdk's own Protocol 1.0 packet handler --------------------------------------
@pytest.fixture
def pty_poppy(poppy: ServoMap) -> Iterator[PtyServer]:
    with pty_served_by_thread(mock_bus_for(poppy, wire_timing=True)) as server:
        yield server


def test_that_unmodified_dynamixel_sdk_protocol_1_0_pings_writes_syncs_and_bulk_reads(pty_poppy: PtyServer) -> None:
    port = PortHandler(pty_poppy.device)
    assert port.openPort() and port.setBaudRate(1_000_000)
    try:
        ph = PacketHandler(1.0)
        assert ph.ping(port, 11) == (29, COMM_SUCCESS, 0)  # MX-28 (1.0 firmware)
        assert ph.ping(port, 36) == (18, COMM_SUCCESS, 0)  # the AX-18A head
        _, result, _ = ph.ping(port, 99)
        assert result != COMM_SUCCESS
        assert ph.write1ByteTxRx(port, 36, 24, 1)[0] == COMM_SUCCESS  # torque on
        assert ph.write2ByteTxRx(port, 36, 30, 600)[0] == COMM_SUCCESS
        assert ph.read2ByteTxRx(port, 36, 30)[:2] == (600, COMM_SUCCESS)
        writer = GroupSyncWrite(port, ph, 30, 2)
        for sid, goal in ((11, 2100), (12, 2000)):
            assert writer.addParam(sid, bytes((goal & 0xFF, goal >> 8)))
        assert writer.txPacket() == COMM_SUCCESS
        # GroupBulkRead's own 1.0 path passes bulkReadTx one argument too many in this SDK
        # release (a TypeError before anything is sent), so its parameters go to the 1.0 packet
        # handler's bulkReadTx and each status is read with readRx, as GroupBulkRead.rxPacket does
        reader = GroupBulkRead(port, ph)
        for sid in (11, 12, 13):
            assert reader.addParam(sid, 30, 2)
        reader.makeParam()
        assert ph.bulkReadTx(port, reader.param, len(reader.param)) == COMM_SUCCESS
        got = []
        for sid in (11, 12, 13):
            data, result, error = ph.readRx(port, sid, 2)
            assert result == COMM_SUCCESS and error == 0
            got.append(data[0] | (data[1] << 8))
        assert got == [2100, 2000, 2048]
        value, result, error = ph.read1ByteTxRx(port, 11, 43)  # present temperature
        assert result == COMM_SUCCESS and error == 0 and 20 <= value <= 40
    finally:
        port.closePort()


# ---- the CLI on a 1.0 robot ---------------------------------------------------------------
@pytest.fixture(scope="module")
def robot1(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The OP3 as a Darwin-OP-class robot: MX-28 with 1.0 firmware on a 1 Mbps Protocol 1.0 bus."""
    root = tmp_path_factory.mktemp("robot1") / "op3"
    shutil.copytree(OP3, root)
    text = (OP3 / "servos.toml").read_text()
    text = text.replace("protocol = 2.0", "protocol = 1.0").replace('model = "XM430-W350"', 'model = "MX-28"')
    text = re.sub(r"baud_rate = \d+", "baud_rate = 1000000", text)
    (root / "servos.toml").write_text(text)
    return root


def test_that_servos_scan_status_torque_and_read_posture_work_on_a_1_0_bus(
        robot1: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from robot_rise.cli import main

    assert main(["servos", "scan", "--mock", "--robot", str(robot1)]) == 0
    out = capsys.readouterr().out
    assert "Protocol 1.0" in out and "MX-28(1.0)" in out and "WRONG MODEL" not in out
    assert "20 servo(s) answered; 0 of the map missing" in out
    assert main(["servos", "status", "--mock", "--robot", str(robot1)]) == 0
    assert len(re.findall(r"\n\s*\d+ \S+\s+-?\d+\.\d{3}\s+\d+\s+12\.0  none", capsys.readouterr().out)) == 20
    assert main(["servos", "torque", "on", "--mock", "--robot", str(robot1)]) == 0
    assert "torque on" in capsys.readouterr().out
    out_file = tmp_path / "p.json"
    assert main(["servos", "read-posture", "--mock", "--robot", str(robot1), "--out", str(out_file)]) == 0
    assert out_file.exists() and "20 joint angles read" in capsys.readouterr().out


def test_that_execute_mock_streams_a_proven_trajectory_on_a_1_0_robot(
        robot1: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from robot_rise.cli import main
    from robot_rise.model import load_robot
    from robot_rise.posture import stand_posture
    from robot_rise.seal import sealed
    from robot_rise.trajectory import Trajectory, write_trajectory

    robot = load_robot(robot1)
    start = stand_posture(robot)
    t = np.linspace(0.0, 0.4, 5)
    q = np.repeat(start.joint_vector(robot.joint_names)[None, :], t.size, axis=0)
    q[:, robot.joint_names.index("r_sho_pitch")] += np.linspace(0.0, 0.2, t.size)
    report = {"proven": True, "robot": robot.name, "robot_digest": robot.digest(), "scene": "flat"}
    path = tmp_path / "arm.json"
    write_trajectory(path, sealed(Trajectory(robot.name, robot.joint_names, t, q, start, report)))  # the test's own "proof", sealed
    log = tmp_path / "run.csv"
    assert main(["execute", str(path), "--mock", "--yes", "--robot", str(robot1), "--log", str(log)]) == 0
    out = capsys.readouterr().out
    assert "preflight: 20/20 servos" in out and "completed" in out and "FAULT" not in out
    assert len(log.read_text().splitlines()) > 40


def test_that_with_protocol_turns_a_2_0_map_into_a_1_0_one_for_the_emulator() -> None:
    smap, replaced = with_protocol(load_servo_map(OP3 / "servos.toml"), 1.0)
    assert smap.protocol == 1.0 and len(replaced) == 20 and replaced[0] == ("XM430-W350", "MX-28")
    assert isinstance(mock_bus_for(smap, wire_timing=False), mb.MockBus1)
