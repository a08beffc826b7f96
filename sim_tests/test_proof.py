"""The Proof in a trajectory's report (the file's keys, read back and validated) and the rule
"may this trajectory run on this robot?" (execution_permit)."""

from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from robot_rise.errors import FormatError, RobotRiseError
from robot_rise.proof import Permit, Proof, execution_permit, prove
from robot_rise.model import Robot
from robot_rise.posture import Posture
from robot_rise.trajectory import Trajectory, read_trajectory, write_trajectory

# The report's proof entries in the file's order (the trajectory@1 format: do not reorder).
PROOF_KEYS = [
    "proven", "problems", "robot", "robot_digest", "scene", "scene_digest", "standing", "judge", "duration_s",
    "peak_torque_ratio", "envelope_limit", "peak_torque_ratio_per_joint", "min_zmp_margin_m", "time_on_feet_s",
    "ground_contacts", "self_collision", "self_touch", "max_self_penetration_m", "stood_from_s",
]


def _proof(**overrides: object) -> Proof:
    values: dict = dict(
        proven=True, problems=(), robot="op3", robot_digest="a" * 64, scene="flat", scene_digest="b" * 64,
        standing=True, judge="STANDING; tilt 1.0 deg", duration_s=2.5, peak_torque_ratio=0.75, envelope_limit=0.9,
        peak_torque_ratio_per_joint={"l_knee": 0.75, "r_knee": 0.5}, min_zmp_margin_m=0.0125, time_on_feet_s=4.0,
        ground_contacts=("l_foot", "r_foot"), self_collision=False, self_touch=False, max_self_penetration_m=0.0,
        stood_from_s=1.5,
    )
    values.update(overrides)
    return Proof(**values)


def _stand(robot: Robot) -> Posture:
    return Posture(robot.name, robot.stand_qpos[:3], robot.stand_qpos[3:7], dict(zip(robot.joint_names, robot.stand_qpos[7:])))


def test_that_to_dict_writes_the_reports_proof_keys_in_the_files_order():
    assert list(_proof().to_dict()) == PROOF_KEYS
    assert list(_proof(proven=False, standing=False, diagnosis="fell").to_dict()) == [*PROOF_KEYS, "diagnosis"]


def test_that_to_dict_writes_lists_and_objects_as_the_json_has_them():
    d = _proof().to_dict()
    assert d["problems"] == [] and d["ground_contacts"] == ["l_foot", "r_foot"]
    assert d["peak_torque_ratio_per_joint"] == {"l_knee": 0.75, "r_knee": 0.5}


def test_that_a_proof_survives_the_trajectory_file(robot, tmp_path):
    tr = Trajectory(robot.name, robot.joint_names, [0.0, 1.0], np.tile(robot.stand_qpos[7:], (2, 1)), _stand(robot))
    proof = _proof(proven=False, standing=False, problems=("not standing: tilt",), diagnosis="fell", min_zmp_margin_m=None, stood_from_s=None)
    path = tmp_path / "t.json"
    write_trajectory(path, tr.with_report(motion="wave", **proof.to_dict(), filter_iterations=2))
    report = read_trajectory(path).report
    assert Proof.from_dict(report) == proof
    assert report["motion"] == "wave" and report["filter_iterations"] == 2  # the rest of the report stays


def test_that_a_replays_proof_writes_the_same_json_it_reads(robot, tmp_path):
    tr = Trajectory(robot.name, robot.joint_names, [0.0, 1.0], np.tile(robot.stand_qpos[7:], (2, 1)), _stand(robot))
    _, _, proof = prove(robot, tr)
    assert proof.proven and proof.robot == robot.name and proof.robot_digest == robot.digest()
    path = tmp_path / "t.json"
    write_trajectory(path, tr.with_report(**proof.to_dict()))
    again = Proof.from_dict(read_trajectory(path).report)
    assert json.dumps(again.to_dict()) == json.dumps(json.loads(path.read_text())["report"])


def test_that_a_null_number_reads_as_nan():
    d = _proof().to_dict() | {"peak_torque_ratio": None}
    assert math.isnan(Proof.from_dict(d).peak_torque_ratio)


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("proven", "yes", "report: proof entry 'proven' must be true or false, got 'yes'"),
        ("peak_torque_ratio", "0.5", "report: proof entry 'peak_torque_ratio' must be a number, got '0.5'"),
        ("duration_s", True, "report: proof entry 'duration_s' must be a number, got True"),
        ("ground_contacts", "l_foot", "report: proof entry 'ground_contacts' must be a list of strings, got 'l_foot'"),
        ("problems", [1], "report: proof entry 'problems' must be a list of strings, got [1]"),
        ("peak_torque_ratio_per_joint", {"l_knee": "x"},
         "report: proof entry 'peak_torque_ratio_per_joint' must be an object of numbers by joint name, got {'l_knee': 'x'}"),
        ("scene", 3, "report: proof entry 'scene' must be a string or null, got 3"),
        ("diagnosis", None, "report: proof entry 'diagnosis' must be a string, got None"),
    ],
)
def test_that_from_dict_names_the_mistyped_entry_in_one_line(key, value, message):
    with pytest.raises(FormatError) as e:
        Proof.from_dict(_proof().to_dict() | {key: value})
    assert str(e.value) == message
    assert isinstance(e.value, RobotRiseError)


def test_that_from_dict_names_a_missing_entry_and_where():
    d = _proof().to_dict()
    del d["robot_digest"]
    with pytest.raises(FormatError, match=r"^rise\.json: proof entry 'robot_digest' missing$"):
        Proof.from_dict(d, where="rise.json")


def test_that_a_proven_report_of_this_robot_may_run(robot):
    report = {"proven": True, "robot": robot.name, "robot_digest": robot.digest(), "scene": "flat"}
    assert execution_permit(report, robot) == Permit(True, "")
    assert execution_permit(_proof(robot=robot.name, robot_digest=robot.digest()), robot).allowed


@pytest.mark.parametrize("proven", [False, None, "true", 1])
def test_that_a_report_not_saying_proven_may_not_run(robot, proven):
    report = {"robot": robot.name} if proven is None else {"proven": proven, "robot": robot.name}
    permit = execution_permit(report, robot)
    assert not permit.allowed
    assert permit.reason == "the trajectory's report does not say it was proven (report.proven is not true)"


def test_that_a_report_not_naming_its_robot_may_not_run(robot):
    permit = execution_permit({"proven": True}, robot)
    assert permit == Permit(False, "the trajectory's report does not name the robot it was proven on (report.robot missing)")


def test_that_a_trajectory_proven_on_another_robot_may_not_run(robot):
    permit = execution_permit(_proof(robot="darwin"), robot)
    assert permit == Permit(False, "the trajectory was proven on robot 'darwin', not 'op3'")


def test_that_a_trajectory_proven_on_changed_robot_files_may_not_run(robot):
    permit = execution_permit({"proven": True, "robot": robot.name, "robot_digest": "0" * 64}, robot)
    assert permit == Permit(False, (
        "the trajectory was proven on another version of robot 'op3': the robot files changed since "
        f"(report.robot_digest 000000000000..., loaded robot {robot.digest()[:12]}...)"))


def test_that_a_report_without_a_digest_may_run_and_the_robot_files_are_not_hashed():
    def no_hashing() -> str:
        raise AssertionError("digest computed")

    robot = SimpleNamespace(name="op3", digest=no_hashing)
    assert execution_permit({"proven": True, "robot": "op3"}, robot).allowed  # type: ignore[arg-type]
