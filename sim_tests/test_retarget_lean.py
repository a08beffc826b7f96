"""Retargeting (paper 000 section 5.3): the dynamics filter adapts the library's lean to a body
with other proportions (robot_rise.filter.lean, lean on arms and feet)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robot_rise.filter import dynamics_filter, join_with_blend, shoulder_pitch_joints, torso_pitch_rad
import robot_rise.filter.loop as filter_loop
from robot_rise.filter.lean import LEAN_MAX_OFFSET_RAD
from robot_rise.library import load_library
from robot_rise.model import compose
from robot_rise.posture import Posture
from robot_rise.retarget import BodyScale, scale_robot
from robot_rise.trajectory import Trajectory


def _quat_y(angle: float, yaw: float = 0.0) -> np.ndarray:
    """Yaw about z, then pitch about the body's y [w, x, y, z]."""
    qz = np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])
    qy = np.array([math.cos(angle / 2), 0.0, math.sin(angle / 2), 0.0])
    w1, x1, y1, z1 = qz
    w2, x2, y2, z2 = qy
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def test_torso_pitch_is_the_forward_lean_whatever_the_heading():
    for yaw in (0.0, 1.0, -2.5):
        got = torso_pitch_rad(np.array([_quat_y(a, yaw) for a in (0.0, 0.3, math.pi / 2, -math.pi / 2)]))
        assert got == pytest.approx([0.0, 0.3, math.pi / 2, -math.pi / 2], abs=1e-9)


def test_the_shoulder_pitch_joints_are_found_from_the_tree_on_a_scaled_robot_too(tmp_path, robot):
    long = scale_robot(robot, tmp_path / "long", BodyScale(arms=1.3, torso=1.2))
    for r in (robot, long):
        joints = shoulder_pitch_joints(r, compose(r, "flat"))
        assert set(joints) == {"l_sho_pitch", "r_sho_pitch"}
        assert joints["l_sho_pitch"] == pytest.approx(-joints["r_sho_pitch"])  # mirrored axes
        assert abs(joints["l_sho_pitch"]) == pytest.approx(1.0)


def test_join_keeps_the_plan_root_then_the_library_root(robot):
    lib = load_library(robot_name=robot.library)
    motion = lib.get(lib.names()[0]).trajectory
    plan = Trajectory(robot.name, motion.joint_names, motion.t[:3], motion.q[:3], motion.start, {}, motion.root[:3])
    joined = join_with_blend(plan, motion, 5)
    assert joined.root is not None and joined.root.shape == (len(joined.t), 7)
    assert np.array_equal(joined.root[:3], motion.root[:3]) and np.array_equal(joined.root[3:], motion.root[5:])
    bare = Trajectory(robot.name, motion.joint_names, motion.t[:3], motion.q[:3], motion.start, {})
    assert join_with_blend(bare, motion, 5).root is None


def _library_motion_on(robot, name: str) -> tuple[Trajectory, Posture]:
    motion = load_library(robot_name=robot.library).get(name)
    st = motion.start
    start = Posture(robot.name, st.root_pos, st.root_quat_wxyz, dict(st.joints))
    tr = motion.trajectory
    return Trajectory(robot.name, tr.joint_names, tr.t, tr.q, start, {}, tr.root), start


@pytest.mark.slow
def test_long_arms_and_torso_rise_on_the_knees_first_motion_only_with_the_lean_adapted(tmp_path, robot, monkeypatch):
    long = scale_robot(robot, tmp_path / "long", BodyScale(arms=1.3, torso=1.2), name="op3_long")
    tr, start = _library_motion_on(long, "prone_knees_first")
    adapted = dynamics_filter(long, tr, start=start)
    assert adapted.proven, adapted.reason
    assert any("lean on arms and feet adapted" in v for h in adapted.iterations for v in h.violations)
    lean = adapted.report["lean_adapted"]
    assert lean["shoulder_joints"] == ["l_sho_pitch", "r_sho_pitch"] and 0.1 < lean["max_offset_rad"] <= LEAN_MAX_OFFSET_RAD
    monkeypatch.setattr(filter_loop, "LEAN_ITERATIONS", 0)  # where the loop reads it
    timing_only = dynamics_filter(long, tr, start=start)
    assert not timing_only.proven and "not standing" in timing_only.reason  # time scaling alone: falls back off its feet


@pytest.mark.slow
def test_a_robot_with_arms_x13_and_torso_x12_rises_from_a_sampled_prone_posture_with_no_code_change(tmp_path, robot):
    from robot_rise.rise import rise
    from robot_rise.sampling import sample_lying

    long = scale_robot(robot, tmp_path / "long", BodyScale(arms=1.3, torso=1.2), name="op3_long")
    posture = sample_lying(long, "prone", 1, seed=4).postures[0]
    result = rise(long, posture)
    assert result.proven, result.reason
    assert result.trajectory.report["robot_digest"] == long.digest() != robot.digest()
    assert "lean_adapted" in result.trajectory.report
