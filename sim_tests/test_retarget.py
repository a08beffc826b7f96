from __future__ import annotations

import mujoco
import numpy as np
import pytest

from robot_rise.errors import ConfigError
from robot_rise.model import compose, model_index
from robot_rise.retarget import BodyScale, scale_robot


def _site_distance(robot, a: str, b: str) -> float:
    m = compose(robot, None)
    d = mujoco.MjData(m)
    idx = model_index(m, robot)
    d.qpos[idx.qpos_root] = robot.stand_qpos[:7]
    mujoco.mj_kinematics(m, d)
    return float(np.linalg.norm(d.site(a).xpos - d.site(b).xpos))


def _body_distance(robot, a: str, b: str) -> float:
    m = compose(robot, None)
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    return float(np.linalg.norm(d.body(a).xpos - d.body(b).xpos))


def test_scaled_arms_are_longer_and_heavier_and_keep_the_library(tmp_path, robot):
    long = scale_robot(robot, tmp_path / "long", BodyScale(arms=1.3, torso=1.2), name="op3_long")
    assert long.name == "op3_long" and long.library == robot.library
    assert long.joint_names == robot.joint_names
    base = _body_distance(robot, "l_sho_roll_link", "l_el_link")
    assert _body_distance(long, "l_sho_roll_link", "l_el_link") == pytest.approx(1.3 * base, rel=1e-3)
    base_sh = _body_distance(robot, "body", "l_sho_pitch_link")
    assert _body_distance(long, "body", "l_sho_pitch_link") > base_sh
    m0, m1 = compose(robot, None), compose(long, None)
    assert m1.body_mass.sum() > m0.body_mass.sum()


def test_scaled_legs_keep_the_stand_keyframe_on_the_ground(tmp_path, robot):
    tall = scale_robot(robot, tmp_path / "tall", BodyScale(legs=1.2))
    m = compose(tall, None)
    d = mujoco.MjData(m)
    idx = model_index(m, tall)
    d.qpos[idx.qpos_root] = tall.stand_qpos[:7]
    d.qpos[idx.qpos_joints] = tall.stand_qpos[7:]
    mujoco.mj_kinematics(m, d)
    assert min(d.site(s).xpos[2] for s in tall.sole_sites) == pytest.approx(0.0, abs=1e-6)
    assert tall.stand_qpos[2] > robot.stand_qpos[2]


def test_scaling_refuses_absurd_factors_and_non_empty_destinations(tmp_path, robot):
    with pytest.raises(ConfigError, match="arms scale 5"):
        BodyScale(arms=5)
    (tmp_path / "x").mkdir()
    (tmp_path / "x" / "keep.txt").write_text("mine")
    with pytest.raises(ConfigError, match="not empty"):
        scale_robot(robot, tmp_path / "x", BodyScale())


def test_a_robot_with_ten_percent_longer_legs_rises_with_no_code_change(tmp_path, robot):
    from robot_rise.rise import rise
    from robot_rise.sampling import sample_lying

    tall = scale_robot(robot, tmp_path / "tall", BodyScale(legs=1.1), name="op3_tall")
    posture = sample_lying(tall, "prone", 1, seed=4).postures[0]
    result = rise(tall, posture)
    assert result.proven, result.reason
    assert result.trajectory.report["robot"] == "op3_tall"
    assert result.trajectory.report["robot_digest"] == tall.digest() != robot.digest()
