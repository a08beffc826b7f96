"""Loose-to-strict refinement, cut and merge, partial-body, key postures and the obstacle scenes."""

from __future__ import annotations

import numpy as np
import pytest

from robot_rise.constants import LOOSE_TO_STRICT_INCREMENT_M, VERIFY_RESOLUTION_M
from robot_rise.model import load_robot
from robot_rise.bench.problems import obstacle_problems
from robot_rise.planning.motion_validator import MotionValidator
from robot_rise.planning.problem import PlanningProblem, PlanStatus
from robot_rise.planning.rrt_blossom.refine import RRTBlossomPlanner, illegal_edge_runs, limbs_of_collisions, loose_to_strict_schedule
from robot_rise.planning.space import PostureSpace
from robot_rise.validity import Collision, ValidityChecker, ValidityReport


@pytest.fixture(scope="module")
def robot():
    return load_robot()


@pytest.fixture(scope="module")
def scenes(robot):
    return {p.scene: p for p in obstacle_problems(robot)}


def _states(seq):
    return np.concatenate([seq.root_pos, seq.root_quat_wxyz, seq.joints], axis=1)


def test_that_the_schedule_starts_with_obstacles_shrunk_to_zero_and_ends_strict(robot, scenes):
    checker = ValidityChecker(robot, "beam")
    p = scenes["beam"]
    sched = loose_to_strict_schedule(checker, [checker.qpos_of(p.start), checker.qpos_of(p.goal)], LOOSE_TO_STRICT_INCREMENT_M)
    assert sched[0].obstacle_shrink_m == pytest.approx(0.35)  # the beam's largest half-size
    assert sched[-1].is_strict
    steps = np.diff([lo.obstacle_shrink_m for lo in sched])
    assert np.all(steps <= 0) and np.all(steps >= -LOOSE_TO_STRICT_INCREMENT_M - 1e-12)


def test_that_flat_ground_needs_a_single_strict_iteration(robot, scenes):
    checker = ValidityChecker(robot, "flat")
    p = scenes["beam"]
    assert [lo.is_strict for lo in loose_to_strict_schedule(checker, [checker.qpos_of(p.start)], 0.025)] == [True]


def test_that_illegal_runs_close_in_time_are_merged():
    bad = np.array([False, True, False, True, False, False, False, True, False])
    assert illegal_edge_runs(bad, 2) == [(1, 4), (7, 8)]
    assert illegal_edge_runs(bad, 1) == [(1, 2), (3, 4), (7, 8)]


def test_that_partial_body_planning_moves_only_the_limbs_in_collision(robot):
    checker = ValidityChecker(robot, "beam")
    arm = ValidityReport(False, (), 0.05, 0.05, -0.01, (Collision("obstacle", "l_forearm", "beam", -0.01),))
    both = ValidityReport(False, (), 0.05, -0.01, 0.05, (Collision("self", "r_foot", "l_shank", -0.01),))
    ground = ValidityReport(False, (), -0.01, 0.05, 0.05, (Collision("ground", "ground", "l_forearm", -0.01),))
    trunk = ValidityReport(False, (), 0.05, 0.05, -0.01, (Collision("obstacle", "torso", "beam", -0.01),))
    assert limbs_of_collisions(robot, checker, arm) == ("left_arm",)
    assert limbs_of_collisions(robot, checker, both) == ("left_leg", "right_leg")
    assert limbs_of_collisions(robot, checker, ground) is None  # ground: full-body
    assert limbs_of_collisions(robot, checker, trunk) is None  # the trunk belongs to no limb


@pytest.mark.parametrize("scene", ["beam", "low_bed", "table"])
def test_that_the_obstacle_scene_is_solved_collision_free(robot, scenes, scene):
    p = scenes[scene]
    checker = ValidityChecker(robot, scene)
    res = RRTBlossomPlanner()(PlanningProblem(p.start, p.goal, checker, budget_s=30.0, seed=0))
    assert res.status is PlanStatus.EXACT_SOLUTION, res.reason
    x = _states(res.path)
    space = PostureSpace.for_robot(robot)
    np.testing.assert_allclose(x[0], space.state(p.start), atol=1e-12)
    np.testing.assert_allclose(x[-1], space.state(p.goal), atol=1e-12)
    fine = MotionValidator(checker, space, VERIFY_RESOLUTION_M / 2)
    assert not fine.illegal_edges(x).any()
    assert res.stats["levels"] > 1  # the obstacle was grown loose-to-strict


def test_that_a_key_posture_is_passed_through(robot, scenes):
    p = scenes["beam"]
    checker = ValidityChecker(robot, "flat")
    key = p.goal.with_root(p.goal.root_pos + np.array([0.0, 0.0, 0.05]))  # the crouch, lifted 5 cm
    assert checker.is_valid(key)
    res = RRTBlossomPlanner()(PlanningProblem(p.start, p.goal, checker, key=key, budget_s=20.0, seed=1))
    assert res.solved, res.reason
    x = _states(res.path)
    k = PostureSpace.for_robot(robot).state(key)
    assert np.min(np.max(np.abs(x - k), axis=1)) < 1e-12


def test_that_an_invalid_key_posture_is_refused(robot, scenes):
    p = scenes["beam"]
    checker = ValidityChecker(robot, "beam")
    key = p.goal.with_root(np.array([0.22, 0.0, 0.05]))  # inside the beam
    res = RRTBlossomPlanner()(PlanningProblem(p.start, p.goal, checker, key=key, budget_s=5.0))
    assert res.status is PlanStatus.INVALID_GOAL and "key posture" in res.reason


@pytest.mark.parametrize("merge_gap, replans", [(2, 1), (1, 2)])
def test_that_cut_and_merge_replans_only_the_illegal_segments_and_keeps_the_rest(robot, merge_gap, replans):
    """Section 4.2.4: legal waypoints around the illegal ones are kept; close illegal runs are replanned as one."""
    from robot_rise.planning.rrt_blossom.refine import PlannerConfig, Run

    checker = ValidityChecker(robot, "flat")
    space = PostureSpace.for_robot(robot)
    x0 = np.asarray(robot.stand_qpos, dtype=float).copy()
    assert checker.is_valid_qpos(space.qpos(x0, checker))
    j = robot.joint_names.index("l_sho_pitch")
    path = np.repeat(x0[None], 9, axis=0)
    path[:, 7 + j] = np.clip(np.linspace(0.0, 0.6, 9) + x0[7 + j], space.lower[j], space.upper[j])
    sunk = path.copy()
    sunk[[2, 5], 2] -= 0.05  # feet 5 cm into the ground at waypoints 2 and 5
    v = MotionValidator(checker, space)
    assert not v.illegal_edges(path).any()
    assert list(np.flatnonzero(v.illegal_edges(sunk))) == [1, 2, 4, 5]
    planner = RRTBlossomPlanner(PlannerConfig(merge_gap=merge_gap))
    run = Run(robot, space, planner.config, np.random.default_rng(0), float("inf"))
    out = planner._repair(run, v, sunk, "test")
    assert not v.illegal_edges(out).any()
    np.testing.assert_array_equal(out[:2], sunk[:2])  # the legal start of the path is kept
    np.testing.assert_array_equal(out[-3:], sunk[-3:])  # and its legal end
    assert not any(np.array_equal(w, sunk[2]) or np.array_equal(w, sunk[5]) for w in out)  # illegal waypoints cut
    assert run.stats["replans"] == replans
    if merge_gap == 1:  # not merged: the legal waypoints between the two runs stay too
        assert any(np.array_equal(w, sunk[3]) for w in out) and any(np.array_equal(w, sunk[4]) for w in out)


def test_that_refinement_with_replanned_segments_is_deterministic_for_a_seed(robot):
    """Loose-to-strict levels and cut-and-merge replans give the same path for the same seed,
    also when a partial-body attempt gives up: it stops after an iteration count, not a time,
    so the full-body search after it starts from the same random state on any machine."""
    from robot_rise.bench.problems import load_problem_set
    from robot_rise.planning.rrt_blossom.refine import PARTIAL_BODY_MAX_ITERATIONS

    p = next(q for q in load_problem_set(robot) if q.name == "beam/library")  # prone beside the beam, frozen goal
    checker = ValidityChecker(robot, "beam")
    a = RRTBlossomPlanner()(PlanningProblem(p.start, p.goal, checker, budget_s=60.0, seed=1))
    b = RRTBlossomPlanner()(PlanningProblem(p.start, p.goal, checker, budget_s=60.0, seed=1))
    assert a.solved and b.solved, (a.reason, b.reason)
    assert a.stats["full_body_replans"] > 0  # the refinement replanned segments
    assert a.stats["partial_body_iterations"] >= PARTIAL_BODY_MAX_ITERATIONS  # and a partial-body attempt gave up
    np.testing.assert_array_equal(_states(a.path), _states(b.path))
