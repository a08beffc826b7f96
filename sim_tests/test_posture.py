from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from robot_rise.cli._common import load_trajectory_for
from robot_rise.errors import PostureError
from robot_rise.posture import (
    LIMIT_CLAMP_TOLERANCE_RAD,
    Posture,
    PostureDistance,
    clamp_to_limits,
    posture_from_dict,
    posture_to_dict,
    quat_multiply,
    read_posture,
    write_posture,
    yaw_rad,
)


def _stand(robot) -> Posture:
    return Posture(robot.name, robot.stand_qpos[:3], robot.stand_qpos[3:7], dict(zip(robot.joint_names, robot.stand_qpos[7:])))


def _yaw(angle: float) -> np.ndarray:
    return np.array([math.cos(angle / 2), 0, 0, math.sin(angle / 2)])


def test_posture_round_trips_through_its_json_file(tmp_path, robot):
    p = _stand(robot)
    write_posture(tmp_path / "p.json", p)
    q = read_posture(tmp_path / "p.json", robot)
    assert np.allclose(q.root_pos, p.root_pos) and np.allclose(q.root_quat_wxyz, p.root_quat_wxyz)
    assert q.joints == pytest.approx(p.joints)
    assert json.loads((tmp_path / "p.json").read_text())["format"] == "robot-rise/posture@1"


@pytest.mark.parametrize(
    "mutate, message",
    [
        (lambda o: o.update(format="robot-rise/posture@2"), "format"),
        (lambda o: o["joints"].update(tail=0.1), "unknown joints tail"),
        (lambda o: o["joints"].pop("l_knee"), "missing joints l_knee"),
        (lambda o: o.update(root_quat=[1, 1, 0, 0]), "not a unit quaternion"),
        (lambda o: o.update(root_quat=[1, 0, 0]), "root_quat"),
        (lambda o: o["joints"].update(l_knee=float("nan")), "NaN"),
        (lambda o: o.update(root_pos=[0, 0, float("inf")]), "NaN or infinity"),
        (lambda o: o["joints"].update(l_knee=3.0), "l_knee=3.0000 not in"),
        (lambda o: o.update(robot="nao"), "robot 'nao'"),
    ],
)
def test_reading_a_bad_posture_names_the_problem(robot, mutate, message):
    obj = posture_to_dict(_stand(robot))
    mutate(obj)
    with pytest.raises(PostureError, match=message):
        posture_from_dict(obj, robot)


def test_limit_tolerance_option_clamps_a_larger_overshoot(robot):
    obj = posture_to_dict(_stand(robot))
    upper = robot.joint_upper[robot.joint_index("l_knee")]
    obj["joints"]["l_knee"] = upper + 0.008
    with pytest.raises(PostureError):
        posture_from_dict(obj, robot)
    assert posture_from_dict(obj, robot, limit_tolerance_rad=0.01).joints["l_knee"] == upper


def test_the_clamp_tolerance_is_four_ticks_of_a_4096_tick_servo_so_a_joint_resting_on_its_stop_is_a_start():
    assert LIMIT_CLAMP_TOLERANCE_RAD == pytest.approx(4 * 2 * math.pi / 4096)
    assert 5.0e-3 < LIMIT_CLAMP_TOLERANCE_RAD < 6.2e-3  # 3-5 mrad past a stop (issue 40: 3.3 mrad) is a start


def _past_limit(robot, joint: str, past_rad: float, *, upper: bool) -> Posture:
    """A lying posture (a library start) with one joint ``past_rad`` past its lower or upper limit."""
    p = read_posture(_LYING, robot)
    i = robot.joint_index(joint)
    return p.with_joints({joint: robot.joint_upper[i] + past_rad if upper else robot.joint_lower[i] - past_rad})


_LYING = Path(__file__).parent.parent / "configs" / "motions" / "op3" / "left_tip_elbow_knees.start.json"  # l_sho_roll rests on its lower stop


@pytest.mark.parametrize("past_rad", [0.3e-3, 3.3e-3, 5.0e-3])
@pytest.mark.parametrize("upper", [False, True])
def test_a_posture_file_up_to_four_ticks_past_a_limit_is_clamped_with_one_warning(robot, tmp_path, caplog, past_rad, upper):
    joint = "l_sho_roll" if not upper else "r_knee"
    write_posture(tmp_path / "p.json", _past_limit(robot, joint, past_rad, upper=upper))
    with caplog.at_level("WARNING", logger="robot_rise.posture"):
        p = read_posture(tmp_path / "p.json", robot)
    i = robot.joint_index(joint)
    assert p.joints[joint] == (robot.joint_upper[i] if upper else robot.joint_lower[i])
    warnings = [r for r in caplog.records if r.levelname == "WARNING"]
    assert len(warnings) == 1
    assert joint in warnings[0].getMessage() and f"{past_rad * 1e3:.2f} mrad" in warnings[0].getMessage()
    q = p.joint_vector(robot.joint_names)
    assert np.all(q >= robot.joint_lower) and np.all(q <= robot.joint_upper)


def test_a_posture_more_than_four_ticks_past_a_limit_is_refused_naming_the_joint(robot, tmp_path):
    write_posture(tmp_path / "p.json", _past_limit(robot, "l_sho_roll", 7e-3, upper=False))
    with pytest.raises(PostureError, match="out of limits: l_sho_roll=-1.3160 not in"):
        read_posture(tmp_path / "p.json", robot)


def test_clamp_to_limits_names_the_joints_clamped_and_leaves_a_posture_inside_alone(robot, caplog):
    inside = read_posture(_LYING, robot)
    assert clamp_to_limits(inside, robot) == (inside, ())
    past = _past_limit(robot, "l_sho_roll", 3.3e-3, upper=False).with_joints({"r_knee": robot.joint_upper[robot.joint_index("r_knee")] + 5e-3})
    with caplog.at_level("WARNING"):
        clamped, names = clamp_to_limits(past, robot)
    assert names == ("l_sho_roll", "r_knee") and not caplog.records  # pure: the warning is admit_posture's
    assert clamped.joints["r_knee"] == robot.joint_upper[robot.joint_index("r_knee")]


def test_the_validity_checker_refuses_a_posture_past_a_limit_until_it_is_clamped(robot):
    from robot_rise.validity import ValidityChecker

    checker = ValidityChecker(robot, "flat")
    past = _past_limit(robot, "l_sho_roll", 0.3e-3, upper=False)
    assert checker.check(past).reasons() == ["joint limit: l_sho_roll=-1.3093 not in [-1.3090, 1.7453] (0.30 mrad past)"]
    assert checker.check(clamp_to_limits(past, robot)[0]).valid


def test_a_settled_posture_resting_5_mrad_past_its_stop_rises(robot, tmp_path, caplog):
    from robot_rise.rise import RiseOptions, rise

    write_posture(tmp_path / "p.json", _past_limit(robot, "l_sho_roll", 5.0e-3, upper=False))
    with caplog.at_level("WARNING", logger="robot_rise.posture"):
        start = read_posture(tmp_path / "p.json", robot)
    assert len(caplog.records) == 1
    assert rise(robot, start, RiseOptions(seed=0)).proven


@pytest.mark.parametrize("past_rad, ok", [(0.3e-3, True), (3.3e-3, True), (5.0e-3, True), (7e-3, False)])
def test_a_trajectory_whose_start_is_past_a_limit_loads_clamped_up_to_four_ticks(robot, tmp_path, caplog, past_rad, ok):
    from robot_rise.trajectory import Trajectory, write_trajectory

    start = _past_limit(robot, "l_sho_roll", past_rad, upper=False)
    q0 = start.joint_vector(robot.joint_names)
    write_trajectory(tmp_path / "t.json", Trajectory(robot.name, robot.joint_names, np.array([0.0, 1.0]), np.stack([q0, q0]), start))
    if not ok:
        with pytest.raises(PostureError, match="t.json: start: joint angles out of limits: l_sho_roll"):
            load_trajectory_for(robot, str(tmp_path / "t.json"))
        return
    with caplog.at_level("WARNING", logger="robot_rise.posture"):
        tr = load_trajectory_for(robot, str(tmp_path / "t.json"))
    assert tr.start.joints["l_sho_roll"] == robot.joint_lower[robot.joint_index("l_sho_roll")]
    assert len(caplog.records) == 1 and "t.json: start: clamped into the joint limits: l_sho_roll" in caplog.text


def test_invalid_json_is_reported_with_the_file_name(tmp_path, robot):
    f = tmp_path / "broken.json"
    f.write_text("{not json")
    with pytest.raises(PostureError, match="broken.json: not valid JSON"):
        read_posture(f, robot)


def test_distance_is_zero_for_identical_postures_and_symmetric(robot):
    metric = PostureDistance.for_robot(robot)
    rng = np.random.default_rng(0)
    q1, q2 = rng.normal(size=(2, 4))
    q1, q2 = q1 / np.linalg.norm(q1), q2 / np.linalg.norm(q2)
    v1, v2 = rng.uniform(robot.joint_lower, robot.joint_upper, size=(2, robot.n_joints))
    assert metric(q1, v1, q1, v1) == pytest.approx(0.0, abs=1e-6)
    assert metric(q1, v1, q2, v2) == pytest.approx(metric(q2, v2, q1, v1))
    assert metric(q1, v1, q2, v2) > 0


def test_distance_ignores_facing_direction_and_sign_of_quaternion(robot):
    metric = PostureDistance.for_robot(robot)
    rng = np.random.default_rng(1)
    tilt = rng.normal(size=4)
    tilt /= np.linalg.norm(tilt)
    v = rng.uniform(robot.joint_lower, robot.joint_upper)
    for yaw in (0.3, 1.7, -2.9):
        assert metric(tilt, v, quat_multiply(_yaw(yaw), tilt), v) == pytest.approx(0.0, abs=1e-3)
    assert metric(tilt, v, -tilt, v) == pytest.approx(0.0, abs=1e-3)


def test_distance_weights_root_by_five_and_head_by_half(robot):
    metric = PostureDistance.for_robot(robot)
    v = np.zeros(robot.n_joints)
    pitch = np.array([math.cos(0.1), 0, math.sin(0.1), 0])  # 0.2 rad tilt: dis Q = 0.1
    assert metric(np.array([1.0, 0, 0, 0]), v, pitch, v) == pytest.approx(5 * 0.1)
    head = v.copy()
    head[robot.joint_index("head_pan")] = 0.4
    assert metric(pitch, v, pitch, head) == pytest.approx(math.sqrt(0.5) * 0.4)


def test_distance_is_vectorised_over_batches(robot):
    metric = PostureDistance.for_robot(robot)
    rng = np.random.default_rng(2)
    quats = rng.normal(size=(50, 4))
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    joints = rng.uniform(robot.joint_lower, robot.joint_upper, size=(50, robot.n_joints))
    batch = metric(quats[0], joints[0], quats, joints)
    one_by_one = [metric(quats[0], joints[0], q, j) for q, j in zip(quats, joints)]
    assert batch.shape == (50,)
    assert np.allclose(batch, one_by_one)


@pytest.mark.parametrize("angle", [0.0, 0.4, -2.0, math.pi - 1e-3])
def test_yaw_is_the_heading_of_the_x_axis_on_the_ground_whatever_the_lean(angle):
    assert yaw_rad(_yaw(angle)) == pytest.approx(angle, abs=1e-12)
    pitched = quat_multiply(_yaw(angle), np.array([math.cos(0.3), 0.0, math.sin(0.3), 0.0]))  # then leaning 0.6 rad forward
    assert yaw_rad(pitched) == pytest.approx(angle, abs=1e-12)


def test_yaw_is_zero_when_the_x_axis_points_straight_up():
    assert yaw_rad(np.array([math.cos(math.pi / 4), 0.0, -math.sin(math.pi / 4), 0.0])) == 0.0


def test_a_posture_written_and_read_back_has_the_same_quaternion_bit_for_bit(robot, tmp_path):
    """A rise output's seal covers its start: reading must not renormalise an already unit quaternion
    (q / |q| is not idempotent in floating point; 1 of 30 fresh rise outputs was refused for it)."""
    rng = np.random.default_rng(0)
    base = read_posture(_LYING, robot)
    changed = 0
    for i in range(200):
        q = rng.normal(size=4)
        p = Posture(robot.name, base.root_pos, q / np.linalg.norm(q), base.joints)
        write_posture(tmp_path / "p.json", p)
        back = read_posture(tmp_path / "p.json", robot)
        changed += not np.array_equal(back.root_quat_wxyz, p.root_quat_wxyz)
    assert changed == 0
    # far from unit (within the tolerance) is still normalised
    p = Posture(robot.name, base.root_pos, np.array([1.0005, 0.0, 0.0, 0.0]), base.joints)
    assert np.linalg.norm(p.root_quat_wxyz) == pytest.approx(1.0, abs=1e-15)
