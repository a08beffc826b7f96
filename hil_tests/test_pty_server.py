"""The emulator on a pseudo-terminal: unmodified dynamixel-sdk and our driver open it like an adapter."""

from __future__ import annotations

import os
import struct
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import serial
from dynamixel_sdk import (
    COMM_SUCCESS,
    GroupSyncRead,
    GroupSyncWrite,
    PacketHandler,
    PortHandler,
)

import drivers.mockbus as mb
from drivers.executor import Executor, ExecutorConfig
from drivers.mockbus.pty_server import PtyServer, PtyServerProcess, spawn_pty_server, tty_baud_rate
from drivers.port import ensure_low_latency
from drivers.protocol import Instruction, decode_packet, encode_packet
from drivers.safety import SafetyLimits
from drivers.servo_map import ServoMap
from drivers.session import connect, mock_bus_for
from drivers.startup import engage, preflight
from hil_tests.conftest import pty_served_by_thread

BAUD = 1_000_000


@pytest.fixture(scope="module")
def server() -> Iterator[PtyServerProcess]:
    with spawn_pty_server([1, 2, 3], baud_rate=BAUD, wire_timing=True) as s:
        yield s


@pytest.fixture
def threaded(servo_map: ServoMap) -> Iterator[PtyServer]:
    """The robot's servo map on a pty served by a thread of this process."""
    with pty_served_by_thread(mock_bus_for(servo_map, wire_timing=True)) as server:
        yield server


def test_that_unmodified_dynamixel_sdk_pings_writes_and_reads_through_the_pty(server: PtyServerProcess) -> None:
    port = PortHandler(server.device)  # the SDK's own class, opening the device path
    assert port.openPort() and port.setBaudRate(BAUD)
    try:
        ph = PacketHandler(2.0)
        assert ph.ping(port, 2) == (1020, COMM_SUCCESS, 0)
        writer = GroupSyncWrite(port, ph, 116, 4)
        for i in (1, 2, 3):
            assert writer.addParam(i, list(struct.pack("<i", 2000 + 10 * i)))
        assert writer.txPacket() == COMM_SUCCESS
        reader = GroupSyncRead(port, ph, 116, 4)
        for i in (1, 2, 3):
            assert reader.addParam(i)
        assert reader.txRxPacket() == COMM_SUCCESS
        assert [reader.getData(i, 116, 4) for i in (1, 2, 3)] == [2010, 2020, 2030]
        assert reader.fastSyncRead() == COMM_SUCCESS
        assert [reader.getData(i, 116, 4) for i in (1, 2, 3)] == [2010, 2020, 2030]
        value, result, error = ph.read1ByteTxRx(port, 3, 7)  # ID register
        assert (value, result, error) == (3, COMM_SUCCESS, 0)
    finally:
        port.closePort()


def test_that_the_pty_has_no_latency_timer_and_the_driver_says_so(server: PtyServerProcess) -> None:
    timer = ensure_low_latency(server.device)
    assert timer.path is None and "no latency timer" in timer.note


def test_that_bytes_sent_at_the_wrong_baud_rate_are_ignored(threaded: PtyServer) -> None:
    assert threaded.device is not None
    ping = encode_packet(1, Instruction.PING)
    with serial.Serial(threaded.device, baudrate=57600, timeout=0.05) as port:
        assert tty_baud_rate(port.fileno()) == 57600
        port.write(ping)
        assert port.read(14) == b""
        port.baudrate = threaded.bus.baud_rate
        port.write(ping)
        reply = decode_packet(port.read(14))
    assert reply.servo_id == 1 and reply.is_status
    assert threaded.stats.dropped_wrong_baud == len(ping)


def test_that_the_driver_preflights_and_streams_over_the_pty(threaded: PtyServer, servo_map: ServoMap) -> None:
    assert threaded.device is not None
    with connect(servo_map, threaded.device) as conn:
        assert "low-latency ioctl not supported" in conn.latency.note
        report = preflight(conn.group)
        assert len(report.found) == len(servo_map) and report.fast_read
        engage(conn.group, watchdog_s=1.0)  # generous: this test is about streaming, not the watchdog, and CI machines stall
        limits = SafetyLimits(servo_map.lower_rad, servo_map.upper_rad)
        t = np.array([0.0, 0.3])
        q = np.zeros((2, len(servo_map)))
        q[1, 0] = 0.05
        run = Executor(conn.group, limits, ExecutorConfig(rate_hz=50.0, hold_s=0.1)).run(servo_map.joint_names, t, q)
    assert run.completed, run.faults
    assert run.stats.cycles >= 15
    assert threaded.stats.replies > 0


def test_that_the_server_links_its_device_and_removes_the_link_on_close(tmp_path: Path) -> None:
    link = tmp_path / "ttyDXL"
    with PtyServer(mb.MockBus.from_ids([4], baud_rate=BAUD), link=link) as server:
        assert server.device is not None and server.device.startswith("/dev/pts/")
        assert os.path.realpath(link) == server.device
    assert not link.exists() and not link.is_symlink()


def test_that_the_spawned_emulator_reports_its_scheduling(server: PtyServerProcess) -> None:
    import subprocess
    import sys

    assert server.scheduling == "normal scheduling"
    probe = "import os; os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(5))"
    permitted = subprocess.run([sys.executable, "-c", probe], capture_output=True).returncode == 0
    with spawn_pty_server([1], baud_rate=BAUD, rt_priority=5) as rt:
        assert rt.scheduling == ("SCHED_FIFO 5" if permitted else "normal scheduling")
        with serial.Serial(rt.device, baudrate=BAUD, timeout=1.0) as port:  # and it still answers
            port.write(encode_packet(1, Instruction.PING))
            assert decode_packet(port.read(14)).servo_id == 1


_STREAMING_HOST = """
import sys
import numpy as np
from drivers.executor import Executor, ExecutorConfig
from drivers.safety import SafetyLimits
from drivers.servo_map import load_servo_map
from drivers.session import connect
from drivers.startup import engage, preflight

smap = load_servo_map(sys.argv[1])
# generous reply margin: the emulator is a thread of the (busy) test process
with connect(smap, sys.argv[2], rx_margin_s=0.25) as conn:
    preflight(conn.group)
    limits = SafetyLimits(smap.lower_rad, smap.upper_rad)
    while True:  # until killed: a host stall longer than the watchdog ends a run (DEADLINE); stream again
        engage(conn.group, watchdog_s=0.1)
        q0 = conn.group.read_feedback().position_rad
        q1 = np.clip(q0 + 0.3, limits.lower_rad, limits.upper_rad)
        print("STREAMING", flush=True)
        Executor(conn.group, limits, ExecutorConfig(rate_hz=50.0)).run(
            smap.joint_names, np.array([0.0, 20.0]), np.vstack([q0, q1]))
"""


def test_that_killing_the_host_process_mid_stream_trips_every_servo_watchdog(
        threaded: PtyServer, servo_map: ServoMap) -> None:
    import signal
    import subprocess
    import sys
    import time

    from hil_tests.conftest import SERVO_MAP

    assert threaded.device is not None
    host = subprocess.Popen([sys.executable, "-c", _STREAMING_HOST, str(SERVO_MAP), threaded.device],
                            stdout=subprocess.PIPE, text=True)
    try:
        assert host.stdout is not None and host.stdout.readline().strip() == "STREAMING"
        time.sleep(0.3)  # a few cycles of motion
        host.send_signal(signal.SIGKILL)  # no stop, no disarm: the host is simply gone
        host.wait(5.0)
    finally:
        if host.poll() is None:
            host.kill()
    servos = [threaded.bus.servo(s.id) for s in servo_map.servos]
    # The emulator thread advances every 10 ms; the loop ends as soon as every watchdog has
    # tripped, so a generous deadline only matters on a starved CI core.
    deadline = time.monotonic() + 15.0
    while time.monotonic() < deadline and not all(s.watchdog_trips for s in servos):
        time.sleep(0.02)
    assert all(s.watchdog_trips == 1 for s in servos)
    for s in servos:  # stopped where they were: goal = present, torque still on (holding)
        assert s.torque_on and abs(s.get("goal_position") - s.get("present_position")) <= 3
