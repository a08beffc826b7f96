"""A measured lying posture made a valid start (robot_rise.start_repair), and the live planner using it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robot_rise.live.estimate import PostureEstimate
from robot_rise.live.planners import RisePlanner
from robot_rise.model import Robot
from robot_rise.posture import Posture, read_posture
from robot_rise.rise import RiseContext
from robot_rise.sampling import classify_lying
from robot_rise.start_repair import RepairConfig, RepairStatus, repair_start
from robot_rise.validity import ValidityChecker

STARTS = Path(__file__).resolve().parents[1] / "configs" / "motions" / "op3"
# (library start, hip pitch joint, direction that folds the thigh onto the torso)
FOLDS = [("left_tip_elbow_knees", "r_hip_pitch", +1), ("supine_backroll_kneel", "l_hip_pitch", -1)]


@pytest.fixture(scope="module")
def checker(robot: Robot) -> ValidityChecker:
    return ValidityChecker(robot, "flat")


def _start(robot: Robot, name: str) -> Posture:
    return read_posture(STARTS / f"{name}.start.json", robot)


def _thigh_pressed_into_torso(robot: Robot, checker: ValidityChecker, name: str, joint: str, sign: int) -> Posture:
    """The library start with ``joint`` folded until the thigh penetrates the torso 4-5 mm."""
    start = _start(robot, name)
    for dq in np.arange(0.005, 2.5, 0.005):
        p = start.with_joints({joint: start.joints[joint] + sign * dq})
        report = checker.check(p)
        depth = max((-c.distance_m for c in report.collisions if c.kind == "self"), default=0.0)
        if depth >= 0.004:
            assert depth <= 0.005, report.reasons()
            assert [(c.kind, {c.geom1, c.geom2}) for c in report.collisions] == [("self", {f"{joint[0]}_thigh", "torso"})]
            return p
    raise AssertionError(f"folding {joint} never pressed the thigh into the torso")


def _sunk(robot: Robot, name: str, depth_m: float = 0.005) -> Posture:
    start = _start(robot, name)
    return start.with_root(start.root_pos - np.array([0.0, 0.0, depth_m]))


@pytest.mark.parametrize("name, joint, sign", FOLDS)
def test_that_a_thigh_pressed_into_the_torso_is_nudged_apart_by_tens_of_mrad(robot, checker, name, joint, sign) -> None:
    pressed = _thigh_pressed_into_torso(robot, checker, name, joint, sign)
    repair = repair_start(pressed, checker)
    assert repair.status is RepairStatus.REPAIRED and repair.valid
    assert checker.check(repair.posture).valid
    assert any("self collision" in r and "thigh / torso" in r for r in repair.before)
    assert repair.after == ()
    # only that leg's hip joints (the chain between thigh and torso) moved, the pitch the most, back the way it folded
    side = joint[0]
    assert {m.joint for m in repair.joint_moves} <= {f"{side}_hip_yaw", f"{side}_hip_roll", f"{side}_hip_pitch"}
    assert repair.joint_moves[0].joint == joint and np.sign(repair.joint_moves[0].delta_rad) == -sign
    assert repair.max_joint_move_rad <= RepairConfig().max_joint_move_rad
    assert repair.lift_m <= 0.002
    assert classify_lying(repair.posture.root_quat_wxyz) == classify_lying(pressed.root_quat_wxyz)
    text = repair.describe()
    assert text.startswith("start repaired (") and joint in text and "mrad" in text


@pytest.mark.parametrize("name", ["prone_elbow_knees", "supine_backroll_kneel", "left_tip_elbow_knees"])
def test_that_a_posture_sunk_5_mm_into_the_floor_is_lifted_and_nothing_else(robot, checker, name) -> None:
    sunk = _sunk(robot, name)
    assert checker.check(sunk).ground_penetration
    repair = repair_start(sunk, checker)
    assert repair.status is RepairStatus.REPAIRED and checker.check(repair.posture).valid
    assert repair.joint_moves == ()
    assert 0.003 <= repair.lift_m <= 0.006
    np.testing.assert_allclose(repair.posture.root_quat_wxyz, sunk.root_quat_wxyz)
    assert "root lifted" in repair.describe()


def test_that_a_valid_start_is_left_as_measured(robot, checker) -> None:
    start = _start(robot, "prone_elbow_knees")
    repair = repair_start(start, checker)
    assert repair.status is RepairStatus.VALID and repair.posture is start
    assert not repair.changed and repair.describe() == ""


def test_that_a_start_too_far_inside_itself_is_a_failed_status_not_an_exception(robot, checker) -> None:
    start = _start(robot, "left_tip_elbow_knees")
    deep = start.with_joints({"r_hip_pitch": start.joints["r_hip_pitch"] + 1.1})
    assert checker.check(deep).self_collision and not checker.check(deep).limit_violations
    repair = repair_start(deep, checker, config=RepairConfig(max_joint_move_rad=0.02))
    assert repair.status is RepairStatus.FAILED and not repair.valid
    assert repair.after and repair.max_joint_move_rad <= 0.02 + 1e-9
    assert repair.describe().startswith("start not repairable")


def test_that_the_repair_bounds_are_checked() -> None:
    with pytest.raises(ValueError, match="max_lift_m"):
        RepairConfig(max_lift_m=float("nan"))
    with pytest.raises(ValueError, match="max_steps"):
        RepairConfig(max_steps=0)


@pytest.fixture(scope="module")
def context(robot: Robot) -> RiseContext:
    return RiseContext.build(robot, "flat")


def _estimate(posture: Posture) -> PostureEstimate:
    return PostureEstimate(posture, (0.0, 0.0, 1.0), classify_lying(posture.root_quat_wxyz), 0.0, True, 0.0, False)  # type: ignore[arg-type]


@pytest.mark.parametrize("kind", ["folded", "sunk"])
def test_that_the_live_planner_repairs_a_measured_start_and_proves_a_get_up_from_it(robot, checker, context, kind) -> None:
    name, joint, sign = FOLDS[1]
    start = _thigh_pressed_into_torso(robot, checker, name, joint, sign) if kind == "folded" else _sunk(robot, name)
    planned = RisePlanner(context, budget_s=5.0).plan(_estimate(start), 1)
    repair = planned.start_repair
    assert repair is not None and repair.status is RepairStatus.REPAIRED
    assert "start posture is not valid" not in planned.reason
    assert planned.proven, planned.reason
    tr = planned.trajectory
    assert tr is not None
    np.testing.assert_allclose(tr.q[0], repair.posture.joint_vector(tr.joint_names), atol=1e-6)
