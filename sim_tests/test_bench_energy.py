"""Tests of robot_rise.planning.bench_energy's files: the lying60 problem cache and the --out results."""

from __future__ import annotations

import json

import pytest

from robot_rise.model import load_robot
from robot_rise.planning import bench_energy as be
from robot_rise.posture import posture_to_dict
from robot_rise.validity import ValidityChecker


@pytest.fixture(scope="module")
def setup():
    robot = load_robot()
    checker = ValidityChecker(robot, "flat")
    return robot, checker, be.crossed_problems(robot, checker, kinds=("crossed_arms",), n=1)[0]


def _cache(problem, per_kind, **extra):
    rows = [{"kind": "supine", "variant": i, "goal_rank": i, "goal_frame": f"m@{i}", "start": posture_to_dict(problem.start),
             "goal": posture_to_dict(problem.goal)} for i in range(per_kind["supine"])]
    return {**extra, "key": {"seed": 1, "per_kind": per_kind}, "library_digest": "0" * 16, "problems": rows}


def test_that_the_lying60_cache_gives_each_problem_its_goal_rank_without_global_state(setup, tmp_path):
    robot, checker, p = setup
    per_kind = {"supine": 2}
    path = tmp_path / "lying.json"
    path.write_text(json.dumps(_cache(p, per_kind)))
    out = be._cached_lying60(robot, checker, 1, per_kind, str(path))
    assert [(q.kind, q.variant, q.goal_rank, q.goal_frame) for q in out] == [("supine", 0, 0, "m@0"), ("supine", 1, 1, "m@1")]
    assert not hasattr(be, "LYING60_GOAL_RANKS")
    assert be.CrossedProblem("k", 0, p.start, p.goal).goal_rank == 0  # crossed-limb problems: the nearest, no frame
