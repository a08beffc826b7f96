"""Standing judge, ZMP (paper 003 eq. 2.11-2.12) and support polygon."""

from __future__ import annotations

import numpy as np
import pytest

import robot_rise.judge as judge_mod
from robot_rise.judge import convex_hull_2d, judge, support_margin, zmp_point_mass
from robot_rise.model import load_robot
from robot_rise.posture import Posture
from robot_rise.sim import Player
from robot_rise.trajectory import Trajectory


def test_every_name_in_all_resolves() -> None:
    for name in judge_mod.__all__:
        assert hasattr(judge_mod, name), name


def test_zmp_of_static_masses_is_the_ground_projection_of_their_centre_of_mass() -> None:
    m = np.array([1.0, 3.0])
    p = np.array([[0.0, 0.0, 0.5], [0.4, 0.2, 0.1]])
    zmp = zmp_point_mass(m, p, np.zeros((2, 3)))
    assert zmp == pytest.approx([0.3, 0.15])


def test_forward_acceleration_moves_the_zmp_backwards() -> None:
    m = np.array([1.0])
    p = np.array([[0.0, 0.0, 0.5]])
    zmp = zmp_point_mass(m, p, np.array([[1.0, 0.0, 0.0]]))
    assert zmp[0] == pytest.approx(-0.5 / 9.81)


def test_convex_hull_drops_interior_points() -> None:
    pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]])
    assert len(convex_hull_2d(pts)) == 4


def test_support_margin_is_positive_inside_and_negative_outside() -> None:
    square = np.array([[0, 0], [0.1, 0], [0.1, 0.1], [0, 0.1]])
    assert support_margin(np.array([0.05, 0.05]), square) == pytest.approx(0.05)
    assert support_margin(np.array([0.15, 0.05]), square) == pytest.approx(-0.05)
    assert support_margin(np.array([0.05, 0.0]), square[:2]) == pytest.approx(0.0)


def _stand_start(robot):  # type: ignore[no-untyped-def]
    sq = robot.stand_qpos
    return Posture(robot.name, sq[:3], sq[3:7], dict(zip(robot.joint_names, sq[7:])))


def test_standing_still_in_the_stand_keyframe_is_judged_standing() -> None:
    robot = load_robot()
    start = _stand_start(robot)
    q = start.joint_vector(robot.joint_names)
    tr = Trajectory(robot.name, robot.joint_names, np.array([0.0, 0.5]), np.stack([q, q]), start)
    rec = Player(robot).play(tr, hold_s=2.5)
    v = judge(rec)
    assert v.standing, v.reason
    assert v.min_zmp_margin_m > 0.01
    assert not v.self_collision
    assert v.peak_envelope_ratio < 0.5


def test_a_robot_that_falls_over_is_not_standing() -> None:
    robot = load_robot()
    start = _stand_start(robot)
    q = start.joint_vector(robot.joint_names)
    lean = q.copy()
    for name, sign in (("l_ank_pitch", 1.0), ("r_ank_pitch", -1.0)):
        lean[robot.joint_index(name)] += sign * 1.0  # feet pitched hard: the robot tips over
    tr = Trajectory(robot.name, robot.joint_names, np.array([0.0, 0.3]), np.stack([q, lean]), start)
    v = judge(Player(robot).play(tr, hold_s=2.5))
    assert not v.standing
    assert v.reason


def test_a_too_short_recording_is_not_standing() -> None:
    robot = load_robot()
    start = _stand_start(robot)
    q = start.joint_vector(robot.joint_names)
    tr = Trajectory(robot.name, robot.joint_names, np.array([0.0, 0.1]), np.stack([q, q]), start)
    v = judge(Player(robot).play(tr, hold_s=1.0))
    assert not v.standing
    assert "stood only" in v.reason or "settled" in v.reason
