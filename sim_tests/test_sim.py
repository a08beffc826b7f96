"""The player: recording shapes, rates, servo torques within the envelope, contacts."""

from __future__ import annotations

import numpy as np
import pytest

import robot_rise.sim as sim
from robot_rise.errors import RobotRiseError
from robot_rise.library_authoring import settle, sym
from robot_rise.model import load_robot
from robot_rise.sim import Player
from robot_rise.trajectory import Trajectory


@pytest.fixture(scope="module")
def robot():  # type: ignore[no-untyped-def]
    return load_robot()


def test_every_name_in_all_resolves() -> None:
    for name in sim.__all__:
        assert hasattr(sim, name), name


def test_recording_covers_the_trajectory_and_the_hold_at_the_record_rate(robot) -> None:  # type: ignore[no-untyped-def]
    start = settle(robot, "supine", sym(sho_roll=1.3))
    q = start.joint_vector(robot.joint_names)
    tr = Trajectory(robot.name, robot.joint_names, np.array([0.0, 1.0]), np.stack([q, q]), start)
    rec = Player(robot).play(tr, hold_s=0.5, record_hz=50)
    assert rec.t.shape == (75,)
    assert rec.t[-1] == pytest.approx(1.5)
    assert rec.q.shape == (75, robot.n_joints) and rec.root_pose.shape == (75, 7)
    assert np.all(np.diff(rec.t) > 0)


def test_a_lying_robot_touches_the_ground_with_more_than_its_feet(robot) -> None:  # type: ignore[no-untyped-def]
    start = settle(robot, "prone", sym(sho_roll=1.3))
    q = start.joint_vector(robot.joint_names)
    tr = Trajectory(robot.name, robot.joint_names, np.array([0.0, 0.2]), np.stack([q, q]), start)
    rec = Player(robot).play(tr, hold_s=0.2)
    assert not rec.on_feet.any()
    assert np.all(np.isnan(rec.zmp_margin_m))
    assert rec.ground_contact[-1].any()


def test_servo_torques_never_exceed_the_envelope_even_for_a_goal_jump(robot) -> None:  # type: ignore[no-untyped-def]
    start = settle(robot, "supine", sym(sho_roll=1.3))
    q = start.joint_vector(robot.joint_names)
    jump = q.copy()
    jump[robot.joint_index("l_sho_pitch")] -= 1.5
    tr = Trajectory(robot.name, robot.joint_names, np.array([0.0, 0.002, 0.6]), np.stack([q, jump, jump]), start)
    rec = Player(robot).play(tr, hold_s=0.1)
    assert rec.peak_envelope_ratio == pytest.approx(1.0, abs=1e-6)  # saturated, never beyond
    assert np.all(rec.envelope_ratio <= 1.0 + 1e-9)
    assert np.all(np.abs(rec.torque_nm) <= 4.1 * (1 + np.abs(rec.qd) / 4.82) + 1e-6)


def test_a_trajectory_for_other_joints_is_rejected(robot) -> None:  # type: ignore[no-untyped-def]
    start = settle(robot, "supine", sym(sho_roll=1.3))
    tr = Trajectory(robot.name, ("head_pan",), np.array([0.0]), np.zeros((1, 1)), start)
    with pytest.raises(RobotRiseError, match="lacks joints"):
        Player(robot).play(tr)
