"""Bus scenarios that run on the emulator by default and on a real bus when ``ROBOT_RISE_PORT``
is set (the ``hardware`` variants are skipped otherwise; the reason is printed at the end of the
run).

On a real bus the scenarios are read-only, except those marked ``motion`` which also need
``ROBOT_RISE_ALLOW_MOTION=1``: they engage torque (goal = present first) and stream the present
posture for half a second; nothing moves beyond holding.
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import numpy as np
import pytest

from drivers.executor import Executor, ExecutorConfig
from drivers.safety import SafetyLimits
from drivers.servo_map import ServoMap
from drivers.session import Connection, connect, mock_url_for
from drivers.startup import disarm_watchdog, engage, preflight


@pytest.fixture(params=["mock", pytest.param("hardware", marks=pytest.mark.hardware)])
def conn(request: pytest.FixtureRequest, servo_map: ServoMap) -> Iterator[Connection]:
    if request.param == "hardware":
        port = os.environ.get("ROBOT_RISE_PORT")
        if not port:
            pytest.skip("needs a real Dynamixel bus: set ROBOT_RISE_PORT=/dev/ttyUSB0")
        if "motion" in request.keywords and os.environ.get("ROBOT_RISE_ALLOW_MOTION") != "1":
            pytest.skip("engages torque on the real robot: set ROBOT_RISE_ALLOW_MOTION=1 as well")
    else:
        port = mock_url_for(servo_map, wire_timing=False)
    with connect(servo_map, port) as c:
        yield c


def test_that_every_mapped_servo_answers_with_its_model(conn: Connection, servo_map: ServoMap) -> None:
    report = preflight(conn.group, configure=False)
    assert sorted(report.found) == sorted(servo_map.ids)
    assert report.hardware_errors == {}


def test_that_feedback_of_every_servo_is_read_in_one_cycle(conn: Connection, servo_map: ServoMap) -> None:
    preflight(conn.group, configure=False)
    conn.group.use_indirect = False  # read-only: the servos' indirect map is left alone
    fb = conn.group.read_feedback()
    assert fb.valid.all() and (fb.voltage_v > 9).all() and not fb.alert.any()
    assert np.all(np.abs(fb.position_rad) < np.pi + 0.1)


def test_that_fast_and_plain_sync_reads_agree_on_present_position(conn: Connection, servo_map: ServoMap) -> None:
    report = preflight(conn.group, configure=False)
    if not report.fast_read:
        pytest.skip("firmware without Fast Sync Read")
    ids = list(servo_map.ids)
    plain = conn.bus.sync_read(132, 4, ids)
    fast = conn.bus.sync_read(132, 4, ids, fast=True)
    assert plain.complete and fast.complete and fast.fast
    ticks = {i: int.from_bytes(plain.data[i], "little", signed=True) for i in ids}
    for i in ids:  # a servo at rest moves by a tick or two of noise between the reads
        assert abs(int.from_bytes(fast.data[i], "little", signed=True) - ticks[i]) <= 4


@pytest.mark.motion
def test_that_engaging_holds_the_present_posture_under_the_watchdog(conn: Connection, servo_map: ServoMap) -> None:
    preflight(conn.group)
    q0 = conn.group.read_feedback().position_rad
    engage(conn.group, watchdog_s=0.2)
    try:
        limits = SafetyLimits(servo_map.lower_rad, servo_map.upper_rad)
        q_hold = np.clip(q0, limits.lower_rad, limits.upper_rad)
        t = np.array([0.0, 0.5])
        run = Executor(conn.group, limits, ExecutorConfig(rate_hz=50.0, hold_s=0.0)).run(
            servo_map.joint_names, t, np.vstack([q_hold, q_hold]))
    finally:
        disarm_watchdog(conn.group)
    assert run.completed, run.faults
    assert run.max_tracking_error_rad < 0.05
