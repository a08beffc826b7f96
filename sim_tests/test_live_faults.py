"""Faults while the live get-up rises on the twin (issue 16): ``robot-rise bench live-faults`` end to end.

Each trial lays the twin down, runs getup on the emulated bus and strikes one fault mid-rise; a
spy on the bus checks every goal written against the servo map's limits.
"""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest

import drivers.mockbus as mb
from drivers.clock import FakeClock
from drivers.servo_map import load_servo_map
from drivers.session import connect, mock_url_for
from robot_rise.bench.live_faults import GoalSpy
from robot_rise.cli import main
from robot_rise.model import Robot


def _bench(*kinds: str, seed: int = 0) -> tuple[int, dict]:
    argv = ["bench", "live-faults", "--trials", "1", "--seed", str(seed), "--json"]
    for kind in kinds:
        argv += ["--kind", kind]
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(argv)
    return code, json.loads(out.getvalue())


def _assert_stopped_safely_in_limits(trial: dict) -> None:
    assert trial["mid_rise"] and trial["stopped_safely"], trial
    assert trial["goal_writes"] > 1000 and trial["out_of_limit"] == 0, trial["out_of_limit_detail"]
    assert trial["motion_after_stop"] == 0 and trial["names_fault"]


def _joint(trial: dict) -> str:
    return trial["target"].split(" (id ")[0]


def test_that_the_goal_spy_catches_a_goal_past_a_limit_and_a_write_it_cannot_read(robot: Robot) -> None:
    smap = load_servo_map(robot.directory / "servos.toml")
    url = mock_url_for(smap, clock=FakeClock())
    bus = mb.attached(url.removeprefix("dxlsim://"))
    assert bus is not None
    goal = smap.servos[0].table["goal_position"]
    try:
        with connect(smap, url) as conn:
            with GoalSpy(bus, smap) as spy:
                q = np.clip(np.zeros(len(smap)), smap.lower_rad, smap.upper_rad)
                conn.group.write_goals(q)
                q[3] = smap.upper_rad[3] + 0.05
                conn.group.write_goals(q)
                conn.bus.sync_write(goal.address + 1, 2, {smap.ids[0]: b"\x00\x00"})  # half a goal
            conn.group.write_goals(q)  # after the spy closed: not seen
    finally:
        mb.detach(url.removeprefix("dxlsim://"))
    assert [w.servo_id for w in spy.out_of_limits()] == [smap.ids[3]]
    assert len(spy.goals) == 2 * len(smap) and spy.partial == 1


@pytest.mark.slow
def test_that_an_overload_and_a_silent_imu_mid_rise_stop_safely_within_limits_and_say_why() -> None:
    code, report = _bench("overload", "imu-silent")
    assert code == 0
    trials = {t["kind"]: t for t in report["trials"]}
    overload, imu = trials["overload"], trials["imu-silent"]
    for trial in (overload, imu):
        _assert_stopped_safely_in_limits(trial)
    # the servo cut its torque: the get-up stops at once, and no new try with a servo in error
    assert overload["halted"] and overload["stop_after_s"] < 0.05 and overload["retries"] == 0
    assert overload["end"] == "limp" and not overload["standing"]
    assert f"{_joint(overload)}: hardware error (overload)" in overload["reason"]
    # blind: the proven get-up runs out (a lost IMU never stops a proven motion half way: that would
    # drop the robot), then the servos hold and no new try is made without it
    assert not imu["halted"] and imu["end"] == "holding" and imu["retries"] == 0
    assert "the IMU stopped answering" in imu["reason"] and "holding" in imu["reason"]
    assert set(report["summary"]) == {"overload", "imu-silent"}


@pytest.mark.slow
def test_that_a_shove_mid_rise_is_seen_by_the_imu_the_servos_go_limp_and_it_rises_again() -> None:
    # the IMU is read in every cycle of the get-up: a torso off the proof's tilt is a fall
    code, report = _bench("push", seed=1)
    assert code == 0
    trial = report["trials"][0]
    _assert_stopped_safely_in_limits(trial)
    assert trial["halted"] and trial["stop_after_s"] < 0.5
    assert "falling at the IMU (id 200): torso tilted" in trial["reason"]
    assert trial["retries"] >= 1 and trial["standing"] and trial["upright"]


@pytest.mark.slow
def test_that_a_servo_that_stops_answering_mid_rise_stops_the_get_up_and_is_named() -> None:
    code, report = _bench("servo-silent")
    (trial,) = report["trials"]
    assert code == 0
    _assert_stopped_safely_in_limits(trial)
    assert trial["halted"] and trial["stop_after_s"] < 0.2 and trial["end"] == "limp" and trial["retries"] == 0
    assert f"servo of {_joint(trial)} did not answer" in trial["reason"]


@pytest.mark.slow
def test_that_a_blocked_joint_mid_rise_stops_each_try_and_is_named() -> None:
    code, report = _bench("blocked")
    (trial,) = report["trials"]
    assert code == 0
    _assert_stopped_safely_in_limits(trial)
    assert trial["halted"] and trial["end"] == "limp" and not trial["standing"]
    assert f"tracking error at {trial['target']}" in trial["reason"]
    # the same joint stopped the second try too: no third one into a blocked joint
    assert trial["retries"] == 1 and "stopped two get-ups in a row (blocked?)" in trial["reason"]
