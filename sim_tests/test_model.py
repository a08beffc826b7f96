from __future__ import annotations

import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest

from robot_rise.errors import ConfigError
from robot_rise.model import compose, load_robot, model_index
from robot_rise.servo import servo_datasheet


def test_default_robot_has_twenty_limited_joints_and_op3_mass_and_height(robot):
    assert robot.n_joints == 20
    assert np.all(robot.joint_lower < robot.joint_upper)
    m = compose(robot, None, with_actuators=False)
    assert 3.3 < m.body_mass.sum() < 3.7
    d = mujoco.MjData(m)
    idx = model_index(m, robot)
    d.qpos[idx.qpos_root] = [0, 0, 0.279, 1, 0, 0, 0]
    mujoco.mj_kinematics(m, d)
    top = max(d.geom_xpos[g][2] + m.geom_rbound[g] for g in idx.robot_geoms if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE)
    sole = min(d.site(s).xpos[2] for s in robot.sole_sites)
    assert 0.49 < top - sole < 0.53


def test_servo_ids_are_one_to_twenty_and_limits_inside_model_ranges(robot):
    assert sorted(s.id for s in robot.servos) == list(range(1, 21))
    for s, lo, hi in zip(robot.servos, robot.joint_lower, robot.joint_upper):
        assert lo <= s.lower < s.upper <= hi


def test_actuators_reproduce_the_xm430_envelope_numbers(robot):
    m = compose(robot, "flat")
    spec = servo_datasheet("XM430-W350")
    kp = spec.position_gain_nm_per_rad(12.0)
    # 800/128 PWM/tick * 4096/2pi tick/rad * 4.1/885 N m/PWM = 18.9 N m/rad (servo.py docstring)
    assert kp == pytest.approx(18.88, abs=0.02)
    assert spec.saturation_error_rad() == pytest.approx(0.217, abs=0.001)
    assert np.allclose(m.actuator_gainprm[:, 0], kp)
    assert np.allclose(m.actuator_forcerange, [[-4.1, 4.1]] * 20)
    idx = model_index(m, robot)
    assert np.allclose(m.dof_damping[idx.dof_joints], 4.1 / (46 * 2 * np.pi / 60) + spec.viscous_damping_nm_s)


def test_stand_keyframe_stands_still_on_flat_ground_with_servos_on(robot):
    m = compose(robot, "flat")
    d = mujoco.MjData(m)
    idx = model_index(m, robot)
    d.qpos[idx.qpos_root] = robot.stand_qpos[:7]
    d.qpos[idx.qpos_joints] = robot.stand_qpos[7:]
    d.ctrl[idx.actuators] = robot.stand_qpos[7:]
    for _ in range(1000):  # 2 s
        mujoco.mj_step(m, d)
    assert abs(d.qpos[2] - robot.stand_qpos[2]) < 0.01
    assert np.max(np.abs(d.qvel)) < 0.05


def test_every_shipped_scene_composes_with_the_robot(robot):
    for scene in ("flat", "beam", "low_bed", "table", "slope", "icy", "soft"):
        m = compose(robot, scene)
        idx = model_index(m, robot)
        assert len(idx.ground_geoms) == 1
        assert m.nu == 20


def test_a_robot_directory_of_the_same_form_loads_without_code_changes(tmp_path: Path, robot):
    copy = tmp_path / "mini"
    shutil.copytree(robot.directory, copy)
    toml = (copy / "robot.toml").read_text().replace('name = "op3"', 'name = "mini"')
    (copy / "robot.toml").write_text(toml)
    other = load_robot(copy)
    assert other.name == "mini"
    assert other.joint_names == robot.joint_names


def test_a_servo_map_naming_an_unknown_joint_is_rejected_with_the_joint_name(tmp_path: Path, robot):
    copy = tmp_path / "bad"
    shutil.copytree(robot.directory, copy)
    text = (copy / "servos.toml").read_text().replace('joint = "l_knee"', 'joint = "l_kneee"')
    (copy / "servos.toml").write_text(text)
    with pytest.raises(ConfigError, match="l_kneee"):
        load_robot(copy)


def test_a_missing_robot_directory_is_a_config_error(tmp_path: Path):
    with pytest.raises(ConfigError, match="does not exist"):
        load_robot(tmp_path / "nowhere")
