"""Lying start postures: the root orientation of each lying kind, and a lying posture dropped onto flat ground to rest.

A motion's start posture is found by dropping the robot in the motion's lying posture onto flat
ground with the servos holding it and letting it settle; the caller checks that it still lies as
the motion says (``robot_rise.sampling.classify_lying``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import mujoco
import numpy as np

from robot_rise.model import Robot, compose, model_index
from robot_rise.posture import Posture, posture_from_qpos, quat_multiply
from robot_rise.validity import ValidityChecker

__all__ = ["DROP_CLEARANCE_M", "SETTLE_S", "quat_lying", "settle"]

SETTLE_S = 1.5  # time a dropped lying posture is simulated to come to rest [s]
DROP_CLEARANCE_M = 0.004  # the lying posture is dropped from this far above the ground [m]


def quat_lying(kind: str, yaw_rad: float = 0.0) -> np.ndarray:
    """Root quaternion (w, x, y, z) of a lying robot: ``supine``, ``prone``, ``left`` or ``right`` side.

    Supine: the torso's front (+x) faces up, head towards -x. Prone: front down, head towards +x.
    Left: the left side (+y) down. Right: the right side down. Then a yaw about world z.
    """
    h = math.pi / 4
    base = {
        "supine": np.array([math.cos(-h), 0.0, math.sin(-h), 0.0]),  # -90 deg about y
        "prone": np.array([math.cos(h), 0.0, math.sin(h), 0.0]),  # +90 deg about y
        "left": np.array([math.cos(-h), math.sin(-h), 0.0, 0.0]),  # -90 deg about x: +y -> -z
        "right": np.array([math.cos(h), math.sin(h), 0.0, 0.0]),  # +90 deg about x: -y -> -z
    }
    if kind not in base:
        raise ValueError(f"unknown lying kind {kind!r}; known: {', '.join(base)}")
    yaw = np.array([math.cos(yaw_rad / 2), 0.0, 0.0, math.sin(yaw_rad / 2)])
    return quat_multiply(yaw, base[kind])


def settle(robot: Robot, lying: str, joints: Mapping[str, float], *, yaw_rad: float = 0.0, settle_s: float = SETTLE_S) -> Posture:
    """Drop the robot in a lying posture onto flat ground with the servos holding it; return the rest posture.

    Args:
        lying: ``supine``, ``prone``, ``left`` or ``right`` (see :func:`quat_lying`).
        joints: joint angles the servos hold [rad], clipped to the joint limits; joints not named hold 0.
        yaw_rad: yaw of the lying robot about world z [rad].
        settle_s: simulated time to come to rest [s].

    Returns:
        the posture at rest, moved back over the origin in x and y.
    """
    q = np.array([joints.get(j, 0.0) for j in robot.joint_names])
    q = np.clip(q, robot.joint_lower, robot.joint_upper)
    quat = quat_lying(lying, yaw_rad)
    pose = Posture(robot.name, np.array([0.0, 0.0, 1.0]), quat, dict(zip(robot.joint_names, q)))
    checker = ValidityChecker(robot, "flat")
    qpos = checker.qpos_of(pose)
    low = checker.lowest_point_z(qpos)
    pose = pose.with_root(root_pos=np.array([0.0, 0.0, 1.0 - low + DROP_CLEARANCE_M]))
    m = compose(robot, "flat")
    d = mujoco.MjData(m)
    idx = model_index(m, robot)
    d.qpos[:] = pose.qpos(robot, idx, m.qpos0)
    d.ctrl[idx.actuators] = q
    for _ in range(int(round(settle_s / m.opt.timestep))):
        mujoco.mj_step(m, d)
    d.qpos[idx.qpos_root[:2]] = 0.0  # back over the origin (x, y only)
    return posture_from_qpos(robot, idx, d.qpos)
