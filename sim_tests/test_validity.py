from __future__ import annotations

import math
import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest

from robot_rise.model import load_robot
from robot_rise.validity import Looseness, ValidityChecker


def _stand_qpos(checker, robot, *, x=0.0, dz=0.0, **joints):
    q = checker.model.qpos0.copy()
    q[checker.index.qpos_root] = robot.stand_qpos[:7]
    q[checker.index.qpos_joints] = robot.stand_qpos[7:]
    q[checker.index.qpos_root[0]] += x
    q[checker.index.qpos_root[2]] += dz
    for name, value in joints.items():
        q[checker.index.qpos_joints[robot.joint_index(name)]] = value
    return q


@pytest.fixture(scope="module")
def flat(robot):
    return ValidityChecker(robot, "flat")


def test_standing_on_the_ground_is_touching_and_valid(flat, robot):
    report = flat.check_qpos(_stand_qpos(flat, robot))
    assert report.valid
    assert abs(report.ground_clearance_m) < 1e-3
    assert flat.is_valid_qpos(_stand_qpos(flat, robot))


def test_sinking_five_millimetres_into_the_ground_is_penetration(flat, robot):
    q = _stand_qpos(flat, robot, dz=-0.005)
    report = flat.check_qpos(q)
    assert not report.valid and report.ground_penetration and not report.self_collision
    assert report.ground_clearance_m == pytest.approx(-0.005, abs=5e-4)
    assert not flat.is_valid_qpos(q)


def test_hovering_two_centimetres_up_is_clear_with_measured_clearance(flat, robot):
    report = flat.check_qpos(_stand_qpos(flat, robot, dz=0.02))
    assert report.valid
    assert report.ground_clearance_m == pytest.approx(0.02, abs=5e-4)


def test_crossed_legs_are_a_self_collision_naming_the_links(flat, robot):
    q = _stand_qpos(flat, robot, l_hip_roll=0.4, r_hip_roll=-0.4)
    report = flat.check_qpos(q)
    assert not report.valid and report.self_collision
    assert any({c.geom1, c.geom2} == {"l_shank", "r_shank"} for c in report.collisions)
    assert not flat.is_valid_qpos(q)


def test_joint_limit_violation_is_reported_by_joint_name(flat, robot):
    q = _stand_qpos(flat, robot, l_knee=2.9)
    report = flat.check_qpos(q)
    assert not report.valid and report.limit_violations[0].startswith("l_knee=2.9")
    assert not flat.is_valid_qpos(q)


def test_standing_under_the_table_hits_it_and_beside_it_is_clear(robot):
    table = ValidityChecker(robot, "table")
    under = table.check_qpos(_stand_qpos(table, robot))
    assert not under.valid and under.obstacle_collision
    assert any("table_top" in (c.geom1, c.geom2) for c in under.collisions)
    beside = table.check_qpos(_stand_qpos(table, robot, x=0.8))
    assert beside.valid and beside.obstacle_clearance_m > 0.04


def test_lying_flat_under_the_table_is_clear(robot):
    table = ValidityChecker(robot, "table")
    q = _stand_qpos(table, robot)
    q[table.index.qpos_root[3:]] = [math.cos(-math.pi / 4), 0, math.sin(-math.pi / 4), 0]  # supine
    q[table.index.qpos_root[2]] = 0.0
    q[table.index.qpos_root[2]] -= table.lowest_point_z(q)
    assert table.is_valid_qpos(q)
    assert 0 < table.check_qpos(q).obstacle_clearance_m


def test_standing_on_the_beam_and_the_bed_is_an_obstacle_collision(robot):
    for scene, x in (("beam", 0.22), ("low_bed", 0.3)):
        checker = ValidityChecker(robot, scene)
        report = checker.check_qpos(_stand_qpos(checker, robot, x=x))
        assert report.obstacle_collision, scene
        assert checker.is_valid_qpos(_stand_qpos(checker, robot, x=1.2)), scene


def test_standing_on_the_slope_at_flat_height_penetrates_uphill(robot):
    slope = ValidityChecker(robot, "slope")
    assert slope.check_qpos(_stand_qpos(slope, robot)).ground_penetration
    assert slope.is_valid_qpos(_stand_qpos(slope, robot, dz=0.02))


def test_icy_and_soft_ground_have_flat_geometry(robot):
    for scene in ("icy", "soft"):
        checker = ValidityChecker(robot, scene)
        assert checker.is_valid_qpos(_stand_qpos(checker, robot))
        assert not checker.is_valid_qpos(_stand_qpos(checker, robot, dz=-0.005))


def test_looseness_lowers_the_ground_and_shrinks_obstacles(robot, flat):
    sunk = _stand_qpos(flat, robot, dz=-0.01)
    assert not flat.is_valid_qpos(sunk)
    assert flat.loosened(Looseness(ground_drop_m=0.02)).is_valid_qpos(sunk)
    table = ValidityChecker(robot, "table")
    q = _stand_qpos(table, robot)
    assert not table.is_valid_qpos(q)
    assert table.loosened(Looseness(obstacle_shrink_m=1.0)).is_valid_qpos(q)
    assert not table.loosened(Looseness(obstacle_shrink_m=0.005)).is_valid_qpos(q)
    assert not table.is_valid_qpos(q)  # loosening made a copy; the strict checker is unchanged


def test_batch_check_agrees_with_single_checks(flat, robot):
    rng = np.random.default_rng(0)
    q = np.tile(_stand_qpos(flat, robot, dz=0.05), (200, 1))
    q[:, flat.index.qpos_joints] = rng.uniform(robot.joint_lower, robot.joint_upper, (200, robot.n_joints))
    batch = flat.valid_batch(q)
    assert batch.tolist() == [flat.check_qpos(row).valid for row in q]
    assert 0 < batch.sum() < 200


def test_obstacle_clearance_is_measured_to_the_nearest_table_leg(robot):
    table = ValidityChecker(robot, "table")
    q = _stand_qpos(table, robot, x=0.34)  # the legs stand at x = +-0.28 m, beside the robot's feet
    m, d = table.model, mujoco.MjData(table.model)
    d.qpos[:] = q
    mujoco.mj_kinematics(m, d)
    fromto = np.zeros(6)
    nearest = min(mujoco.mj_geomDistance(m, d, int(g), int(o), 1.0, fromto) for g in table.index.robot_geoms for o in table.index.obstacle_geoms)
    assert nearest < 0.03
    assert table.check_qpos(q).obstacle_clearance_m == pytest.approx(nearest, abs=0.003)


def _robot_dir_with(tmp_path: Path, robot, name: str, text_before_worldbody_end: str = "", contact: str = "") -> Path:
    copy = tmp_path / name
    shutil.copytree(robot.directory, copy)
    xml = (copy / "robot.xml").read_text()
    xml = xml.replace('<site name="torso" pos="0 0 0"/>', '<site name="torso" pos="0 0 0"/>' + text_before_worldbody_end, 1)
    if contact:
        xml = xml.replace("</mujoco>", f"<contact>{contact}</contact></mujoco>")
    (copy / "robot.xml").write_text(xml)
    return copy


def test_links_the_model_excludes_from_contact_are_no_self_collision(tmp_path, robot, flat):
    excluded = load_robot(_robot_dir_with(tmp_path, robot, "excl", contact='<exclude body1="l_knee_link" body2="r_knee_link"/>'))
    checker = ValidityChecker(excluded, "flat")
    q = _stand_qpos(checker, excluded, l_hip_roll=0.4, r_hip_roll=-0.4)
    assert any({c.geom1, c.geom2} == {"l_shank", "r_shank"} for c in flat.check_qpos(q).collisions)
    assert not any({c.geom1, c.geom2} == {"l_shank", "r_shank"} for c in checker.check_qpos(q).collisions)


def test_a_visual_geom_neither_collides_nor_counts_for_the_lowest_point(tmp_path, robot, flat):
    shell = '<geom name="shell" type="sphere" size="0.4" contype="0" conaffinity="0" group="2"/>'
    visual = load_robot(_robot_dir_with(tmp_path, robot, "vis", shell))
    checker = ValidityChecker(visual, "flat")
    q = _stand_qpos(checker, visual)
    assert checker.check_qpos(q).valid
    assert checker.lowest_point_z(q) == flat.lowest_point_z(_stand_qpos(flat, robot))
