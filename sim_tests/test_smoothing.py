"""Smoothing (paper 000 section 4.3): shortcut + end-clamped cubic B-spline, re-verified."""

from __future__ import annotations

import numpy as np
import pytest

from robot_rise.constants import VERIFY_RESOLUTION_M
from robot_rise.model import load_robot
from robot_rise.planning.bench_problems import obstacle_problems
from robot_rise.planning.motion_validator import MotionValidator
from robot_rise.planning.problem import PlanningProblem
from robot_rise.planning.refine import RRTBlossomPlanner
from robot_rise.planning.smoothing import _bspline_points, bspline_samples, smooth_path
from robot_rise.planning.space import PostureSpace
from robot_rise.planning.to_trajectory import path_length
from robot_rise.validity import ValidityChecker


@pytest.fixture(scope="module")
def robot():
    return load_robot()


@pytest.fixture(scope="module")
def beam_case(robot):
    p = next(q for q in obstacle_problems(robot) if q.scene == "beam")
    checker = ValidityChecker(robot, "beam")
    res = RRTBlossomPlanner()(PlanningProblem(p.start, p.goal, checker, budget_s=30.0, seed=2))
    assert res.solved, res.reason
    return checker, res.path, smooth_path(res.path, checker, seed=2)


def _states(seq):
    return np.concatenate([seq.root_pos, seq.root_quat_wxyz, seq.joints], axis=1)


def test_that_the_smoothed_path_keeps_both_end_postures(beam_case):
    _, raw, smooth = beam_case
    np.testing.assert_allclose(_states(smooth)[0], _states(raw)[0], atol=1e-9)
    np.testing.assert_allclose(_states(smooth)[-1], _states(raw)[-1], atol=1e-9)


def test_that_the_smoothed_path_is_legal_at_a_finer_resolution_than_it_was_verified(beam_case, robot):
    checker, _, smooth = beam_case
    v = MotionValidator(checker, PostureSpace.for_robot(robot), VERIFY_RESOLUTION_M / 2)
    assert not v.illegal_edges(_states(smooth)).any()
    assert np.all(smooth.joints >= robot.joint_lower - 1e-9) and np.all(smooth.joints <= robot.joint_upper + 1e-9)


def test_that_smoothing_does_not_lengthen_the_path(beam_case):
    checker, raw, smooth = beam_case
    assert path_length(smooth, checker) <= path_length(raw, checker) + 1e-6


def test_that_smoothing_is_deterministic_for_a_seed(beam_case):
    checker, raw, smooth = beam_case
    again = smooth_path(raw, checker, seed=2)
    np.testing.assert_array_equal(_states(again), _states(smooth))


def test_that_smoothing_does_not_depend_on_how_fast_the_machine_is(beam_case, monkeypatch):
    """A clock that jumps 10 s per reading (a very loaded machine) gives the same smoothed path."""
    import robot_rise.planning.smoothing as sm

    checker, raw, smooth = beam_case
    now = [0.0]

    def slow() -> float:
        now[0] += 10.0
        return now[0]

    monkeypatch.setattr(sm.time, "monotonic", slow)
    again = smooth_path(raw, checker, seed=2)
    np.testing.assert_array_equal(_states(again), _states(smooth))


def test_that_tripled_control_points_reproduce_the_polyline(robot):
    """The local fallback: a piece whose control points are all tripled is the straight polyline."""
    checker = ValidityChecker(robot, None)
    space = PostureSpace.for_robot(robot)
    v = MotionValidator(checker, space)
    rng = np.random.default_rng(0)
    ctrl = np.stack([np.concatenate([[0.0, 0.0, 0.5 + 0.1 * i], robot.stand_qpos[3:7], rng.uniform(-0.3, 0.3, robot.n_joints)]) for i in range(4)])
    pts, _ = _bspline_points(ctrl, np.full(4, 3), space, 0.01, v)
    for x in pts:  # every sample lies on one of the polyline's edges
        on_edge = False
        for a, b in zip(ctrl[:-1], ctrl[1:]):
            s = np.clip(np.dot(x[7:] - a[7:], b[7:] - a[7:]) / np.dot(b[7:] - a[7:], b[7:] - a[7:]), 0, 1)
            on_edge |= np.allclose(x[7:], a[7:] + s * (b[7:] - a[7:]), atol=1e-9)
        assert on_edge


def test_that_the_clamped_bspline_starts_and_ends_on_its_end_control_points(robot):
    checker = ValidityChecker(robot, None)
    space = PostureSpace.for_robot(robot)
    v = MotionValidator(checker, space)
    ctrl = np.stack([np.concatenate([[0.1 * i, 0.0, 0.5], robot.stand_qpos[3:7], np.full(robot.n_joints, 0.1 * i)]) for i in range(5)])
    pts = bspline_samples(ctrl, space, v)
    np.testing.assert_allclose(pts[0], ctrl[0], atol=1e-12)
    np.testing.assert_allclose(pts[-1], ctrl[-1], atol=1e-12)
