"""Time parameterisation within servo velocity and acceleration limits."""

from __future__ import annotations

import numpy as np
import pytest

from robot_rise.model import load_robot
from robot_rise.planning.problem import PostureSequence
from robot_rise.planning.timing import TimingLimits, measured_rates, time_parameterize


@pytest.fixture(scope="module")
def robot():
    return load_robot()


def _seq(robot, joints: np.ndarray, z: np.ndarray | None = None) -> PostureSequence:
    k = len(joints)
    pos = np.zeros((k, 3))
    pos[:, 2] = 0.3 if z is None else z
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (k, 1))
    return PostureSequence(robot.name, robot.joint_names, pos, quat, joints)


def test_that_the_velocity_limits_come_from_the_servo_no_load_speed(robot):
    lim = TimingLimits.from_robot(robot, speed_fraction=0.5)
    expected = np.array([s.no_load_speed_rad_s for s in robot.servo_datasheets()]) * 0.5
    np.testing.assert_allclose(lim.joint_velocity_rad_s, expected)


def test_that_a_timed_path_keeps_every_limit_and_its_end_postures(robot):
    rng = np.random.default_rng(0)
    joints = np.cumsum(rng.uniform(-0.2, 0.2, (12, robot.n_joints)), axis=0)
    joints = np.clip(joints, robot.joint_lower, robot.joint_upper)
    seq = _seq(robot, joints, np.linspace(0.1, 0.25, 12))
    tp = time_parameterize(seq, robot)
    lim = TimingLimits.from_robot(robot)
    vr, ar = measured_rates(tp.t, tp.root, tp.joints, lim)
    assert vr <= 1.0 + 1e-6 and ar <= 1.0 + 1e-6
    assert tp.t[0] == 0.0 and np.all(np.diff(tp.t) > 0)
    np.testing.assert_allclose(tp.joints[0], joints[0], atol=1e-9)
    np.testing.assert_allclose(tp.joints[-1], joints[-1], atol=1e-9)
    np.testing.assert_allclose(tp.root[-1, :3], seq.root_pos[-1], atol=1e-9)


def test_that_a_single_joint_move_follows_a_trapezoidal_profile(robot):
    d = 1.0
    joints = np.zeros((2, robot.n_joints))
    joints[1, 3] = d
    lim = TimingLimits(np.full(robot.n_joints, 2.0), np.full(robot.n_joints, 8.0))
    tp = time_parameterize(_seq(robot, joints), robot, limits=lim, sample_period_s=0.01, jerk_window_s=0.0)
    v, a = 2.0, 8.0
    trapezoid = d / v + v / a  # accelerate to v, cruise, decelerate: 0.75 s
    assert tp.duration_s == pytest.approx(trapezoid, rel=0.05)
    constant_speed_floor = d / v  # the paper's constant-speed profile, ignoring acceleration
    assert tp.duration_s > constant_speed_floor
    vel = np.diff(tp.joints[:, 3]) / np.diff(tp.t)
    assert vel.max() == pytest.approx(v, rel=0.02)


def test_that_a_single_posture_gives_a_single_row(robot):
    tp = time_parameterize(_seq(robot, np.zeros((1, robot.n_joints))), robot)
    assert tp.t.tolist() == [0.0] and tp.joints.shape == (1, robot.n_joints)


def test_that_the_default_profile_limits_jerk_at_the_cost_of_one_window(robot):
    from robot_rise.planning.timing import JERK_WINDOW_S

    joints = np.zeros((2, robot.n_joints))
    joints[1, 3] = 1.0
    lim = TimingLimits(np.full(robot.n_joints, 2.0), np.full(robot.n_joints, 8.0))
    plain = time_parameterize(_seq(robot, joints), robot, limits=lim, sample_period_s=0.005, jerk_window_s=0.0)
    smooth = time_parameterize(_seq(robot, joints), robot, limits=lim, sample_period_s=0.005)
    assert smooth.duration_s == pytest.approx(plain.duration_s + JERK_WINDOW_S, abs=0.02)

    def peak_jerk(tp):
        x = tp.joints[:, 3]
        dt = np.diff(tp.t).mean()
        return np.abs(np.diff(x, 3)).max() / dt**3

    assert peak_jerk(smooth) < 0.25 * peak_jerk(plain)
    assert smooth.max_velocity_ratio <= 1 + 1e-6 and smooth.max_accel_ratio <= 1 + 1e-6


def test_that_the_spacing_of_a_paths_samples_does_not_slow_it(robot):
    """A smoothed curve's samples are unevenly spaced; the path is timed by its length, so a
    straight move sampled at alternating spacings takes as long as the same move in one step
    (timed by the waypoint index, each change of spacing was a velocity jump slowed for)."""
    lim = TimingLimits(np.full(robot.n_joints, 2.0), np.full(robot.n_joints, 8.0))
    steps = np.tile([0.001] * 8 + [0.008] * 8, 14)[:190]  # 1.0 rad in 190 uneven steps
    steps *= 1.0 / steps.sum()
    joints = np.zeros((steps.size + 1, robot.n_joints))
    joints[:, 3] = np.concatenate([[0.0], np.cumsum(steps)])
    joints[:, 5] = -0.5 * joints[:, 3]
    uneven = time_parameterize(_seq(robot, joints), robot, limits=lim)
    even = time_parameterize(_seq(robot, joints[[0, -1]]), robot, limits=lim)
    assert uneven.duration_s == pytest.approx(even.duration_s, rel=0.03)
    vr, ar = measured_rates(uneven.t, uneven.root, uneven.joints, lim)
    assert vr <= 1.0 + 1e-6 and ar <= 1.0 + 1e-6
    np.testing.assert_allclose(uneven.joints[-1], joints[-1], atol=1e-9)


def test_that_a_repeated_waypoint_neither_stops_nor_breaks_the_timing(robot):
    lim = TimingLimits(np.full(robot.n_joints, 2.0), np.full(robot.n_joints, 8.0))
    joints = np.zeros((3, robot.n_joints))
    joints[1:, 3] = 1.0
    once = time_parameterize(_seq(robot, joints[[0, 1]]), robot, limits=lim)
    for path in (joints, joints[[0, 0, 1]]):  # repeated at the end, at the start
        timed = time_parameterize(_seq(robot, path), robot, limits=lim)
        assert timed.duration_s == pytest.approx(once.duration_s, rel=1e-6)
        assert np.all(np.isfinite(timed.joints)) and timed.joints[-1, 3] == 1.0
    middle = np.zeros((4, robot.n_joints))
    middle[1:3, 3], middle[3, 3] = 0.5, 1.0  # repeated halfway: no stop there
    assert time_parameterize(_seq(robot, middle), robot, limits=lim).duration_s == pytest.approx(once.duration_s, rel=0.02)
