from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest

from robot_rise.errors import ConfigError
from robot_rise.model import compose, load_robot, model_files, model_index
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


def _with_supply(robot, tmp_path: Path, value: str):
    copy = tmp_path / "supplied"
    shutil.copytree(robot.directory, copy)
    text = (copy / "servos.toml").read_text().replace("[bus]\n", f"[bus]\nsupply_voltage_v = {value}\n", 1)
    (copy / "servos.toml").write_text(text)
    return copy


def test_the_servo_maps_supply_voltage_sets_the_servos_torque_and_a_variant_scales_it(tmp_path: Path, robot):
    from robot_rise.sim.player import Player
    from robot_rise.sim.variants import ENSEMBLE

    four_cell = load_robot(_with_supply(robot, tmp_path, "14.8"))
    assert robot.supply_voltage_v == 12.0 and four_cell.supply_voltage_v == 14.8
    sheet = servo_datasheet(robot.servos[0].model)
    nominal, strong = Player(robot, "flat"), Player(four_cell, "flat")
    acts = strong.index.actuators
    np.testing.assert_allclose(nominal.model.actuator_forcerange[acts, 1], sheet.stall_torque_at(12.0))
    np.testing.assert_allclose(strong.model.actuator_forcerange[acts, 1], sheet.stall_torque_at(14.8))
    np.testing.assert_allclose(strong.servos.no_load_speed_rad_s, sheet.no_load_speed_at(14.8))
    low = next(v for v in ENSEMBLE if v.supply_scale != 1.0)  # the ensemble's low supply: relative to each robot's
    weak = Player(four_cell, "flat", variant=low)
    np.testing.assert_allclose(weak.model.actuator_forcerange[acts, 1], sheet.stall_torque_at(14.8 * low.supply_scale))
    assert sheet.stall_torque_at(12.0) < weak.model.actuator_forcerange[acts[0], 1] < sheet.stall_torque_at(14.8)
    # what plans and times motions uses the same supply: faster, harder servos
    from robot_rise.planning import TimingLimits

    np.testing.assert_allclose(TimingLimits.from_robot(four_cell).joint_velocity_rad_s / TimingLimits.from_robot(robot).joint_velocity_rad_s,
                               sheet.no_load_speed_at(14.8) / sheet.no_load_speed_at(12.0))
    np.testing.assert_allclose(four_cell.joint_accel_limits_rad_s2(0.5) / robot.joint_accel_limits_rad_s2(0.5),
                               sheet.stall_torque_at(14.8) / sheet.stall_torque_at(12.0), rtol=1e-6)


@pytest.mark.parametrize("value", ["48.0", '"twelve"'])
def test_a_supply_voltage_that_no_servo_runs_on_is_one_line_naming_it(tmp_path: Path, robot, value):
    with pytest.raises(ConfigError, match="supply_voltage_v must be a number of volts in 5..30") as e:
        load_robot(_with_supply(robot, tmp_path, value))
    assert "\n" not in str(e.value)


def test_a_missing_robot_directory_is_a_config_error(tmp_path: Path):
    with pytest.raises(ConfigError, match="does not exist"):
        load_robot(tmp_path / "nowhere")


def test_the_digest_of_a_robot_of_three_files_is_their_hash_and_its_servo_figures(robot, tmp_path):
    h = hashlib.sha256()
    for name in ("robot.toml", "robot.xml", "servos.toml"):
        h.update((robot.directory / name).read_bytes())
    for sheet in sorted({repr(s) for s in robot.servo_datasheets()}):
        h.update(sheet.encode())
    assert model_files(robot.xml_path) == ()
    assert robot.digest() == h.hexdigest()
    # the servo figures a proof rests on are part of it: a robot's own servo_models.toml changes it
    copy = tmp_path / "op3"
    shutil.copytree(robot.directory, copy)
    from robot_rise.servo import product_catalog_path

    text = product_catalog_path().read_text()
    assert "stall_torque_nm = 4.1," in text
    (copy / "servo_models.toml").write_text(text.replace("stall_torque_nm = 4.1,", "stall_torque_nm = 4.0,", 1))
    weaker = load_robot(copy)
    assert weaker.servo_datasheets()[0].stall_torque_nm == 4.0
    assert weaker.digest() != robot.digest()


TETRAHEDRON = "v 0 0 0\nv 0.03 0 0\nv 0 0.03 0\nv 0 0 0.03\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


def _robot_with_mesh_and_include(tmp_path: Path, robot) -> Path:
    copy = tmp_path / "meshy"
    shutil.copytree(robot.directory, copy)
    (copy / "parts" / "meshes").mkdir(parents=True)
    (copy / "parts" / "meshes" / "bump.obj").write_text(TETRAHEDRON)
    (copy / "parts" / "assets.xml").write_text('<mujoco><asset><mesh name="bump" file="bump.obj"/></asset></mujoco>')
    xml = (copy / "robot.xml").read_text()
    xml = xml.replace('<compiler angle="radian" autolimits="true"/>', '<compiler angle="radian" autolimits="true" meshdir="parts/meshes"/>\n  <include file="parts/assets.xml"/>')
    xml = xml.replace('<site name="torso" pos="0 0 0"/>', '<site name="torso" pos="0 0 0"/><geom name="bump" type="mesh" mesh="bump" pos="0 0 0.2"/>', 1)
    (copy / "robot.xml").write_text(xml)
    return copy


def test_the_digest_covers_the_meshes_and_included_files_the_model_loads(tmp_path: Path, robot):
    directory = _robot_with_mesh_and_include(tmp_path, robot)
    meshy = load_robot(directory)
    assert [p.relative_to(directory.resolve()).as_posix() for p in model_files(meshy.xml_path)] == ["parts/assets.xml", "parts/meshes/bump.obj"]
    before = meshy.digest()
    assert before != robot.digest()
    (directory / "parts" / "meshes" / "bump.obj").write_text(TETRAHEDRON.replace("v 0 0 0.03", "v 0 0 0.031"))
    after_mesh = meshy.digest()
    assert after_mesh != before
    (directory / "parts" / "assets.xml").write_text('<mujoco><asset><mesh name="bump" file="bump.obj" scale="1 1 1"/></asset></mujoco>')
    assert meshy.digest() != after_mesh


def test_a_mesh_file_the_model_names_but_that_is_missing_is_a_config_error(tmp_path: Path, robot):
    directory = _robot_with_mesh_and_include(tmp_path, robot)
    meshy = load_robot(directory)
    (directory / "parts" / "meshes" / "bump.obj").unlink()
    with pytest.raises(ConfigError, match="bump.obj"):
        meshy.digest()


def test_a_robot_with_collision_filters_composes_with_a_scene_and_keeps_them(tmp_path: Path, robot):
    copy = tmp_path / "filters"
    shutil.copytree(robot.directory, copy)
    xml = (copy / "robot.xml").read_text().replace(
        "</mujoco>", '<contact><exclude body1="l_knee_link" body2="r_knee_link"/><pair geom1="l_shank" geom2="r_foot"/></contact></mujoco>'
    )
    (copy / "robot.xml").write_text(xml)
    m = compose(load_robot(copy), "flat")
    a, b = (mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, n) for n in ("l_knee_link", "r_knee_link"))
    assert m.exclude_signature.tolist() == [(min(a, b) << 16) + max(a, b)]
    assert m.npair == 1 and {m.geom(int(m.pair_geom1[0])).name, m.geom(int(m.pair_geom2[0])).name} == {"l_shank", "r_foot"}
