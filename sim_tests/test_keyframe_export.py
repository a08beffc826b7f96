"""robot-rise export-keyframes: a trajectory as MuJoCo keyframes of the robot's own model (issue 42)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from xml.etree import ElementTree

import mujoco
import numpy as np
import pytest

from robot_rise.cli import main
from robot_rise.keyframe_export import KEYFRAMES_FORMAT, trajectory_keyframes
from robot_rise.model import Robot, load_robot
from robot_rise.paths import configs_dir
from robot_rise.trajectory import Trajectory, read_trajectory

MOTION = configs_dir() / "motions" / "op3" / "prone_elbow_knees_quick.json"  # shipped, with root rows


@pytest.fixture(scope="module")
def robot() -> Robot:
    return load_robot(None)


def _with_keys(model_xml: Path, keys_xml: Path, tmp_path: Path) -> mujoco.MjModel:
    """The robot's model with the key file included, as a user would load it."""
    wrapper = tmp_path / f"with_{keys_xml.stem}.xml"
    wrapper.write_text(f'<mujoco><include file="{model_xml.resolve()}"/><include file="{keys_xml.resolve()}"/></mujoco>')
    return mujoco.MjModel.from_xml_path(str(wrapper))


def _expected_qpos(m: mujoco.MjModel, robot: Robot, tr: Trajectory, k: int) -> tuple[np.ndarray, np.ndarray]:
    """(qpos addresses, values) of row k: the root free joint, then each joint by name.

    The root quaternion made unit length: the file rounds it to 6 decimals and MuJoCo normalizes
    a key's quaternion on loading.
    """
    root = int(m.jnt_qposadr[m.body_jntadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, robot.root_body)]])
    adr = [*range(root, root + 7), *(int(m.joint(j).qposadr[0]) for j in tr.joint_names)]
    pose = np.array(tr.root[k] if tr.root is not None else np.r_[tr.start.root_pos, tr.start.root_quat_wxyz])
    pose[3:] /= np.linalg.norm(pose[3:])
    return np.array(adr), np.r_[pose, tr.q[k]]


def test_that_each_row_is_a_key_mujoco_loads_with_the_robots_model(robot: Robot, tmp_path: Path, capsys) -> None:
    out = tmp_path / "keys.xml"
    assert main(["export-keyframes", str(MOTION), "--out", str(out)]) == 0
    assert f"wrote {out}: 169 keys for robot.xml of robot op3" in capsys.readouterr().out
    root = ElementTree.parse(out).getroot()  # well-formed XML
    assert root.tag == "mujoco" and [c.tag for c in root] == ["keyframe"]
    assert KEYFRAMES_FORMAT in out.read_text().splitlines()[1]  # the format string, in the leading comment
    tr = read_trajectory(MOTION)
    m = _with_keys(robot.xml_path, out, tmp_path)
    own = len(robot.keyframes)  # the model's own keys (stand) come first
    assert m.nkey == own + len(tr.t)
    for k in range(len(tr.t)):
        key = m.key(own + k)
        assert key.name == f"prone_elbow_knees_quick_{k:03d}" and key.time[0] == pytest.approx(tr.t[k], abs=1e-12)
        adr, want = _expected_qpos(m, robot, tr, k)
        np.testing.assert_allclose(key.qpos[adr], want, rtol=0, atol=1e-9)


def test_that_without_root_rows_the_keys_take_the_start_posture_root(robot: Robot) -> None:
    tr = dataclasses.replace(read_trajectory(MOTION), root=None)
    keys = trajectory_keyframes(robot, tr)
    m = mujoco.MjModel.from_xml_path(str(robot.xml_path))
    for k in (0, len(tr.t) // 2, len(tr.t) - 1):
        adr, want = _expected_qpos(m, robot, tr, k)
        np.testing.assert_allclose(keys.qpos[k, adr], want, rtol=0, atol=1e-9)


def test_that_rate_resamples_from_the_first_row_to_the_last(robot: Robot, tmp_path: Path, capsys) -> None:
    out = tmp_path / "keys30.xml"
    assert main(["export-keyframes", str(MOTION), "--out", str(out), "--rate", "30", "--json"]) == 0
    obj = json.loads(capsys.readouterr().out)
    tr = read_trajectory(MOTION)
    assert obj["keys"] == int(np.floor(tr.duration_s * 30 + 0.5)) + 1 and obj["nu"] == 0
    keys = trajectory_keyframes(robot, tr, rate_hz=30)
    m = _with_keys(robot.xml_path, out, tmp_path)
    for k, row in ((0, 0), (len(keys.names) - 1, len(tr.t) - 1)):
        adr, want = _expected_qpos(m, robot, tr, row)
        np.testing.assert_allclose(m.key(len(robot.keyframes) + k).qpos[adr], want, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(keys.qpos[:, 3:7], axis=1), 1.0, atol=1e-5)  # slerped unit quaternions


def test_that_a_four_bar_knee_gets_its_rods_solved_and_its_actuators_the_targets(tmp_path: Path) -> None:
    from robot_rise.bench.import_cases import SERVO, write_case
    from robot_rise.keyframe_export import keyframes_xml
    from robot_rise.linkage import constraint_residual, linkage_of
    from robot_rise.posture import stand_posture
    from robot_rise.robot_import import import_robot

    case = write_case("four_bar_knee", tmp_path / "src")
    directory = import_robot(case.model, tmp_path / "robot", servos=case.servos, package_paths=case.package_paths,
                             servo_models=None if case.servos else {"*": SERVO}).directory
    robot = load_robot(directory)
    # the robot file with actuators of its own: position servos on the driven joints, one motor
    text = robot.xml_path.read_text()
    acts = "".join(f'<position name="act_{j}" joint="{j}" kp="10"/>' for j in robot.joint_names[1:])
    robot.xml_path.write_text(text[: text.rindex("</mujoco>")] + f'<actuator><motor name="motor" joint="{robot.joint_names[0]}"/>{acts}</actuator></mujoco>')
    robot = load_robot(directory)
    start = stand_posture(robot)
    knee = robot.joint_names.index("l_knee")
    q = np.tile(start.joint_vector(robot.joint_names), (3, 1))
    q[:, knee] += [0.0, 0.3, 0.6]
    tr = Trajectory(robot.name, robot.joint_names, np.array([0.0, 0.5, 1.0]), q, start, {})
    keys = trajectory_keyframes(robot, tr, name="bend")
    out = tmp_path / "bend.xml"
    out.write_text(keyframes_xml(keys))
    m = _with_keys(robot.xml_path, out, tmp_path)
    assert m.nu == keys.ctrl.shape[1] == robot.n_joints and keys.loop_residual < 1e-6
    linkage = linkage_of(m, robot.passive_joints)
    d = mujoco.MjData(m)
    rocker, knee_adr = int(m.joint("l_knee_rocker").qposadr[0]), int(m.joint("l_knee").qposadr[0])
    for k in range(3):
        key = m.key(len(robot.keyframes) + k)
        d.qpos[:] = key.qpos
        assert np.abs(constraint_residual(m, d, linkage.equalities)).max() < 1e-6  # the loop is closed
        assert key.qpos[rocker] == pytest.approx(key.qpos[knee_adr], abs=1e-3)  # a parallelogram: the rocker turns as the knee
        assert key.ctrl[0] == 0.0  # the motor: no position target
        for a in range(1, m.nu):
            joint = m.joint(m.actuator_trnid[a, 0]).name
            assert key.ctrl[a] == pytest.approx(q[k, robot.joint_names.index(joint)], abs=1e-12)


def test_that_another_robots_trajectory_is_one_error_line(robot: Robot, tmp_path: Path, capsys) -> None:
    from robot_rise.trajectory import trajectory_to_dict

    path = tmp_path / "other.json"
    obj = trajectory_to_dict(read_trajectory(MOTION))
    obj["robot"] = "other"
    obj["start"]["robot"] = "other"
    path.write_text(json.dumps(obj))
    assert main(["export-keyframes", str(path), "--out", str(tmp_path / "k.xml")]) == 2
    err = capsys.readouterr().err
    assert [ln for ln in err.splitlines() if ln.startswith("error:")] == ["error: trajectory is for robot 'other', not 'op3'"]
    assert not (tmp_path / "k.xml").exists()
