"""robot-rise plan: files in, a trajectory with root rows out; clear failures."""

from __future__ import annotations

import json

import numpy as np
import pytest

from robot_rise.cli import main
from robot_rise.model import load_robot
from robot_rise.bench.problems import obstacle_problems
from robot_rise.posture import write_posture
from robot_rise.trajectory import read_trajectory
from robot_rise.validity import ValidityChecker


@pytest.fixture(scope="module")
def beam(tmp_path_factory):
    robot = load_robot()
    p = next(q for q in obstacle_problems(robot) if q.scene == "beam")
    d = tmp_path_factory.mktemp("plan")
    write_posture(d / "lying.json", p.start)
    write_posture(d / "crouch.json", p.goal)
    return robot, p, d


def test_that_plan_writes_a_trajectory_from_the_lying_to_the_connecting_posture(beam, capsys):
    robot, p, d = beam
    out = d / "traj.json"
    rc = main(["plan", "--from", str(d / "lying.json"), "--to", str(d / "crouch.json"), "--scene", "beam", "--seed", "1", "--out", str(out)])
    assert rc == 0
    assert "wrote" in capsys.readouterr().out
    tr = read_trajectory(out)
    assert tr.root is not None and tr.root.shape == (len(tr.t), 7)
    np.testing.assert_allclose(tr.q[0], p.start.joint_vector(robot.joint_names), atol=1e-5)
    np.testing.assert_allclose(tr.q[-1], p.goal.joint_vector(robot.joint_names), atol=1e-5)
    np.testing.assert_allclose(tr.root[-1, :3], p.goal.root_pos, atol=1e-5)
    checker = ValidityChecker(robot, "beam")
    qpos = np.tile(checker.model.qpos0, (len(tr.t), 1))  # every row re-checked kinematically
    qpos[:, checker.index.qpos_root] = tr.root
    qpos[:, checker.index.qpos_joints] = tr.q
    assert checker.first_invalid(qpos) == -1
    assert tr.report["planner"]["status"] == "exact solution"


def test_that_plan_fails_with_exit_1_and_no_file_when_the_goal_is_in_collision(beam, capsys):
    robot, p, d = beam
    bad = p.goal.with_root(np.array([0.22, 0.0, 0.05]))  # inside the beam
    write_posture(d / "bad.json", bad)
    out = d / "none.json"
    rc = main(["plan", "--from", str(d / "lying.json"), "--to", str(d / "bad.json"), "--scene", "beam", "--budget", "2", "--out", str(out)])
    assert rc == 1
    assert not out.exists()
    err = capsys.readouterr().err
    assert "invalid goal" in err and "obstacle collision" in err


def test_that_plan_without_to_selects_the_connecting_posture_from_the_library(beam, capsys):
    _, _, d = beam
    rc = main(["plan", "--from", str(d / "lying.json"), "--budget", "20", "--out", str(d / "x.json")])
    assert rc == 0
    assert "connecting posture:" in capsys.readouterr().err
    assert (d / "x.json").exists()


def test_that_the_energy_planner_is_selectable_from_the_cli(beam, capsys):
    _, _, d = beam
    rc = main(["plan", "--planner", "energy", "--from", str(d / "lying.json"), "--to", str(d / "crouch.json"), "--scene", "beam", "--out", str(d / "e.json")])
    assert rc in (0, 1)  # energy descent may stop in a local minimum; it must say so cleanly
    if rc == 0:
        assert (d / "e.json").exists()
    else:
        assert "no path" in capsys.readouterr().err


def test_that_plan_prints_a_json_summary_on_request(beam, capsys):
    _, _, d = beam
    rc = main(["plan", "--from", str(d / "lying.json"), "--to", str(d / "crouch.json"), "--scene", "beam", "--json", "--out", str(d / "t2.json")])
    assert rc == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["status"] == "exact solution" and summary["rows"] > 2


def _key(robot, p):
    """The lying posture with both elbows bent 0.3 rad: legal, and not a library posture."""
    from robot_rise.posture import Posture

    j = dict(p.start.joints)
    j["l_el"] -= 0.3
    j["r_el"] += 0.3
    return Posture(robot.name, p.start.root_pos, p.start.root_quat_wxyz, j)


def test_that_plan_with_a_key_and_no_goal_passes_the_key_and_connects_it_to_the_library(beam, capsys):
    """Paper 000 section 5.1: a key posture not in the library is connected to the library by planning again."""
    from robot_rise.rise import RiseContext, select_goal

    robot, p, d = beam
    key = _key(robot, p)
    write_posture(d / "key.json", key)
    rc = main(["plan", "--from", str(d / "lying.json"), "--key", str(d / "key.json"), "--seed", "2", "--budget", "20", "--out", str(d / "k.json")])
    assert rc == 0, capsys.readouterr().err
    assert "connecting posture:" in capsys.readouterr().err
    tr = read_trajectory(d / "k.json")
    expected = select_goal(RiseContext.build(robot, "flat"), p.start, key)
    assert expected.key is key  # not in the library: passed through, then the library posture nearest it
    np.testing.assert_allclose(tr.q[-1], expected.goal.joint_vector(robot.joint_names), atol=1e-5)
    kv = key.joint_vector(robot.joint_names)
    assert np.min(np.max(np.abs(tr.q - kv), axis=1)) < 0.02  # a timed row within 0.02 rad of the key posture


def test_that_the_smoothed_path_passes_exactly_through_the_key_posture(beam):
    from robot_rise.planning.problem import PlanningProblem
    from robot_rise.planning.space import PostureSpace
    from robot_rise.planning.to_trajectory import plan_trajectory

    robot, p, _ = beam
    key = _key(robot, p)
    checker = ValidityChecker(robot, "beam")
    out = plan_trajectory(PlanningProblem(p.start, p.goal, checker, key=key, budget_s=20.0, seed=1))
    assert out.trajectory is not None, out.result.reason
    space = PostureSpace.for_robot(robot)
    sm = out.smoothed
    x = np.concatenate([sm.root_pos, sm.root_quat_wxyz, sm.joints], axis=1)
    assert float(np.min(space.distance(x, space.state(key)))) < 1e-9


def test_that_a_key_posture_from_the_library_is_the_goal_itself(beam):
    """A key posture that is a (placed) library posture needs no second leg: it is the goal."""
    from robot_rise.rise import RiseContext, select_goal

    robot, p, _ = beam
    ctx = RiseContext.build(robot, "flat")
    first = select_goal(ctx, p.start)
    assert first.key is None and first.source
    again = select_goal(ctx, p.start, first.goal)
    assert again.key is None and again.goal is first.goal
