"""Rising on a slope: turn the library's flat-ground stance to the ground's tilt.

Paper 000 section 5.2 rises on a 10 deg slope; ours: from the moment the robot is on its feet
the ankles take up the ground's tilt and the legs' lengths its difference across the feet, in
the heading the robot really stands in (:func:`slope_stance_offsets`), so the body above them
stays vertical.
"""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np

from robot_rise.proof.timeline import feet_from
from robot_rise.model import Robot, model_index
from robot_rise.posture import Posture, yaw_rad
from robot_rise.sim.player import Recording
from robot_rise.trajectory import Trajectory

__all__ = [
    "SLOPE_MIN_RAD",
    "SLOPE_RAMP_S",
    "ground_tilt_vector",
    "stand_facing_x",
    "ankle_joints",
    "slope_ankle_offsets",
    "leg_joints",
    "slope_stance_offsets",
    "turn_stance_to_slope",
]

# Slope handling (paper 000 section 5.2, rising on a slope; ours: the stance is turned to the slope).
SLOPE_MIN_RAD = math.radians(1.0)  # ground tilts below this are treated as level
SLOPE_RAMP_S = 0.3  # the ankle offsets are ramped in over this long before the robot is on its feet [s]
SLOPE_LEG_JOINTS = 4  # joints per leg the slope stance adjusts, from the sole up (ankle roll, pitch, knee, hip pitch)
ANKLE_JOINTS = 2  # joints per leg that take up the ground's tilt, from the sole up (ankle roll, pitch)


def ground_tilt_vector(model: mujoco.MjModel, ground_geoms: np.ndarray) -> np.ndarray:
    """Rotation vector (world) [rad] that turns the vertical into the ground's normal, shape (3,).

    Its direction is the axis the ground is tilted about, its length the tilt angle; zero for
    level ground. The ground is the first plane among ``ground_geoms`` (world geoms, so their
    ``geom_quat`` is their world orientation); zero when there is none.
    """
    for g in np.asarray(ground_geoms, dtype=int):
        if int(model.geom_type[g]) != int(mujoco.mjtGeom.mjGEOM_PLANE):
            continue
        mat = np.zeros(9)
        mujoco.mju_quat2Mat(mat, model.geom_quat[g])
        n = mat.reshape(3, 3)[:, 2]
        axis = np.cross([0.0, 0.0, 1.0], n)
        s = float(np.linalg.norm(axis))
        if s < 1e-12:
            return np.zeros(3)
        return axis / s * math.atan2(s, float(n[2]))
    return np.zeros(3)


def stand_facing_x(robot: Robot, model: mujoco.MjModel) -> mujoco.MjData:
    """Kinematics of the ``stand`` keyframe at zero yaw: the frame of a robot standing facing +x."""
    d = mujoco.MjData(model)
    stand = Posture(robot.name, np.array([0.0, 0.0, robot.stand_qpos[2]]), np.array([1.0, 0.0, 0.0, 0.0]), dict(zip(robot.joint_names, robot.stand_qpos[7:])))
    d.qpos[:] = stand.qpos(robot, model_index(model, robot), d.qpos)
    mujoco.mj_kinematics(model, d)
    return d


def ankle_joints(robot: Robot, model: mujoco.MjModel) -> dict[str, np.ndarray]:
    """The ANKLE_JOINTS hinge joints nearest each sole (:func:`leg_joints`), with their axes in the robot's frame.

    Found from the kinematic tree, so a retargeted robot needs no names. Axes are those of the
    ``stand`` keyframe at zero yaw [unit vectors], i.e. in the frame of a robot standing facing +x.
    """
    d = stand_facing_x(robot, model)
    return {
        name: d.xaxis[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)].copy()
        for joints in leg_joints(robot, model, per_leg=ANKLE_JOINTS).values()
        for name in joints
    }


def slope_ankle_offsets(axes: dict[str, np.ndarray], tilt_world: np.ndarray, heading_rad: float) -> dict[str, float]:
    """Ankle angle offsets [rad] that keep the body vertical with the feet flat on tilted ground.

    A foot flat on ground tilted by the rotation vector ``s`` (world) turns the leg above it by
    ``s`` too; an ankle joint of axis ``a`` turned by ``theta`` turns the leg by ``-theta a``
    relative to the foot, so ``theta = s_h . a`` per ankle joint undoes the tilt (to first order;
    10 deg is 0.17 rad), with ``s_h`` the tilt in the frame of the robot facing ``heading_rad``.

    Args:
        axes: ankle joint axes in the robot's frame (:func:`ankle_joints`).
        tilt_world: ground tilt rotation vector [rad] (:func:`ground_tilt_vector`), shape (3,).
        heading_rad: the standing robot's yaw (its +x direction) [rad].
    """
    c, s = math.cos(heading_rad), math.sin(heading_rad)
    tw = np.asarray(tilt_world, dtype=float)
    s_h = np.array([c * tw[0] + s * tw[1], -s * tw[0] + c * tw[1], tw[2]])
    return {name: float(s_h @ a) for name, a in axes.items()}


def leg_joints(robot: Robot, model: mujoco.MjModel, per_leg: int = SLOPE_LEG_JOINTS) -> dict[str, list[str]]:
    """The ``per_leg`` hinge joints nearest each sole (ankle roll and pitch, knee, hip pitch), per sole site."""
    names = set(robot.joint_names)
    out: dict[str, list[str]] = {}
    for site in robot.sole_sites:
        body = int(model.site_bodyid[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site)])
        found: list[str] = []
        while body > 0 and len(found) < per_leg:
            for j in range(int(model.body_jntadr[body]), int(model.body_jntadr[body]) + int(model.body_jntnum[body])):
                if int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_HINGE) and model.joint(j).name in names:
                    found.append(model.joint(j).name)
            body = int(model.body_parentid[body])
        out[site] = found[:per_leg]
    return out


def slope_stance_offsets(
    robot: Robot, model: mujoco.MjModel, joints: np.ndarray, tilt_world: np.ndarray, heading_rad: float, *, iterations: int = 4
) -> dict[str, float]:
    """Leg joint offsets [rad] for standing upright with both soles flat on tilted ground.

    Starts from :func:`slope_ankle_offsets` (the ankles take up the tilt) and adds what the ankles
    cannot: across the slope the uphill foot must be higher, so the legs' lengths differ (knee and
    hip pitch). Gauss-Newton on the stance ``joints`` with the root upright at ``heading_rad``:
    residuals are each sole's normal against the ground's (2 per sole) and the soles' height
    difference along the ground normal [m]; least-norm steps over the SLOPE_LEG_JOINTS joints of
    each leg (:func:`leg_joints`), Jacobian by finite differences of ``mj_kinematics``.

    Args:
        robot: the robot.
        model: a composed model of it (any scene).
        joints: the stance's joint angles in ``robot.joint_names`` order [rad], shape (n,).
        tilt_world: ground tilt rotation vector [rad] (:func:`ground_tilt_vector`).
        heading_rad: the standing robot's yaw [rad].
    """
    idx = model_index(model, robot)
    sites = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, s) for s in robot.sole_sites]
    legs = leg_joints(robot, model)
    free = [n for site in robot.sole_sites for n in legs[site]]
    tw = np.asarray(tilt_world, dtype=float)
    angle = float(np.linalg.norm(tw))
    normal = np.array([0.0, 0.0, 1.0])
    if angle > 0:
        mat = np.zeros(9)
        quat = np.zeros(4)
        mujoco.mju_axisAngle2Quat(quat, tw / angle, angle)
        mujoco.mju_quat2Mat(mat, quat)
        normal = mat.reshape(3, 3)[:, 2]
    d = mujoco.MjData(model)
    base = np.asarray(joints, dtype=float)
    offsets = dict.fromkeys(free, 0.0)
    offsets.update({k: v for k, v in slope_ankle_offsets(ankle_joints(robot, model), tw, heading_rad).items() if k in offsets})

    def residual(off: dict[str, float]) -> np.ndarray:
        d.qpos[idx.qpos_root] = [0.0, 0.0, 1.0, math.cos(heading_rad / 2), 0.0, 0.0, math.sin(heading_rad / 2)]
        d.qpos[idx.qpos_joints] = base + np.array([off.get(n, 0.0) for n in robot.joint_names])
        mujoco.mj_kinematics(model, d)
        r = []
        for sid in sites:
            r.extend(np.cross(d.site_xmat[sid].reshape(3, 3)[:, 2], normal)[:2])
        r.append(float((d.site_xpos[sites[0]] - d.site_xpos[sites[1]]) @ normal))
        return np.array(r)

    eps = 1e-5
    for _ in range(iterations):
        r0 = residual(offsets)
        jac = np.empty((r0.size, len(free)))
        for c, n in enumerate(free):
            trial = dict(offsets)
            trial[n] += eps
            jac[:, c] = (residual(trial) - r0) / eps
        step = np.linalg.lstsq(jac, -r0, rcond=None)[0]
        for c, n in enumerate(free):
            offsets[n] += float(step[c])
    return offsets


def turn_stance_to_slope(
    robot: Robot, tr: Trajectory, rec: Recording, model: mujoco.MjModel, tilt_world: np.ndarray
) -> tuple[Trajectory, dict[str, Any]] | None:
    """``tr`` with the leg offsets of :func:`slope_stance_offsets` (for its final stance) from when
    the robot is on its feet (ramped in over SLOPE_RAMP_S before), in the heading it stood in on
    ``rec``; None if it never was."""
    k = feet_from(rec, tr.duration_s)
    if k is None:
        return None
    t_feet = float(rec.t[k])
    heading = yaw_rad(rec.root_pose[k, 3:])
    final = tr.q[-1, [tr.joint_names.index(n) for n in robot.joint_names]]
    offsets = slope_stance_offsets(robot, model, final, tilt_world, heading)
    w = np.clip((tr.t - (t_feet - SLOPE_RAMP_S)) / SLOPE_RAMP_S, 0.0, 1.0)
    q = tr.q.copy()
    for name, off in offsets.items():
        j = tr.joint_names.index(name)
        r = robot.joint_index(name)
        q[:, j] = np.clip(q[:, j] + w * off, robot.joint_lower[r], robot.joint_upper[r])
    info = {"on_feet_from_s": t_feet, "heading_rad": heading, "tilt_rad": float(np.linalg.norm(tilt_world)), "leg_offsets_rad": offsets}
    return Trajectory(tr.robot, tr.joint_names, tr.t, q, tr.start, tr.report, tr.root), info
