"""Retargeting's lean: a body of other proportions, propped on arms and feet, leans as the library did.

Paper 000 section 5.3: a body with other proportions rises on the same library, the dynamics
filter adapting the motion; ours: the posture is adapted, not only the timing. Propped on its
arms, a body with longer arms or a longer torso than the library's holds its torso at another
lean than the library motion did, and comes onto its feet with its centre of mass behind (or
ahead of) them. While an arm and a foot both touch the world, each arm's shoulder pitch takes up
the difference between the library's torso pitch (its simulated root) and the simulated one;
the offset is kept to the end (released, the arm would push again).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from robot_rise.filter.slope import SLOPE_RAMP_S, stand_facing_x
from robot_rise.model import Robot
from robot_rise.sim.player import Recording
from robot_rise.sim.standing import world_contact
from robot_rise.trajectory import Trajectory

__all__ = [
    "LEAN_MAX_OFFSET_RAD",
    "LEAN_ITERATIONS",
    "ArmLever",
    "torso_pitch_rad",
    "shoulder_pitch_joints",
    "arm_levers",
    "lean_offsets",
    "adapt_lean",
]

LEAN_MIN_RAD = math.radians(3.0)  # smoothed lean errors below this are left alone
LEAN_MAX_STEP_RAD = math.radians(10.0)  # the lean error fed back per row and iteration is clipped to this
LEAN_GAIN = 1.5  # shoulder offset per radian of lean error (a propped arm turns the torso by about 0.55 of it: op3 x1.3 arms)
LEAN_MAX_OFFSET_RAD = 0.6  # total shoulder pitch offset at most [rad]
LEAN_SMOOTH_S = 0.15  # the lean error is smoothed with a Gaussian of this width [s]
LEAN_ITERATIONS = 4  # filter iterations that may adapt the lean (on top of max_iterations)
LEAN_MIN_AXIS = 0.7  # a shoulder pitch joint's axis is at least this much along the body's y axis


def torso_pitch_rad(root_quat_wxyz: np.ndarray) -> np.ndarray:
    """Forward lean of the torso about its own y axis [rad] (positive: leaning forward), shape (K,).

    ``atan2(-x_z, z_z)`` of the torso's x and z axes in the world: 0 upright, +pi/2 lying face
    down, -pi/2 lying on the back, whatever the heading.
    """
    quats = np.atleast_2d(np.asarray(root_quat_wxyz, dtype=float))
    w, x, y, z = (quats / np.linalg.norm(quats, axis=1, keepdims=True)).T
    x_z = 2 * (x * z - w * y)  # rotation matrix entries (2, 0) and (2, 2)
    z_z = w * w - x * x - y * y + z * z
    return np.arctan2(-x_z, z_z)


@dataclass(frozen=True)
class ArmLever:
    """An arm's shoulder pitch joint, the y component of its axis, and the arm's geoms (columns)."""

    joint: str
    axis_y: float
    geoms: np.ndarray


def shoulder_pitch_joints(robot: Robot, model: mujoco.MjModel) -> dict[str, float]:
    """Each arm's shoulder pitch joint -> the y component of its axis in the torso's frame [unit].

    Arms are the limbs named ``*arm*`` in robot.toml; of an arm's hinges, the one nearest the
    torso whose axis (``stand`` keyframe) is at least LEAN_MIN_AXIS along the torso's y axis.
    With the arm propped on the world, turning it by ``-lean * y`` leans the torso forward by
    about ``lean``. A name-to-axis view of what ``dynamics_filter`` adapts (its ``lean_adapted``
    report).
    """
    return {a.joint: a.axis_y for a in arm_levers(robot, model, np.zeros(0, dtype=int))}


def arm_levers(robot: Robot, model: mujoco.MjModel, robot_geoms: np.ndarray) -> list[ArmLever]:
    """Each arm's shoulder pitch joint (as :func:`shoulder_pitch_joints` finds it), with the columns
    of ``robot_geoms`` (geom ids) that belong to the arm below it."""
    d = stand_facing_x(robot, model)

    def depth(body: int) -> int:
        n = 0
        while body > 0:
            body = int(model.body_parentid[body])
            n += 1
        return n

    def under(body: int, top: int) -> bool:
        while body > 0:
            if body == top:
                return True
            body = int(model.body_parentid[body])
        return False

    out = []
    for limb, joints in robot.limbs.items():
        if "arm" not in limb:
            continue
        ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in joints]
        ids = [j for j in ids if j >= 0 and int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_HINGE)]
        pitch = [j for j in ids if abs(float(d.xaxis[j][1])) >= LEAN_MIN_AXIS]
        if not pitch:
            continue
        j = min(pitch, key=lambda j: depth(int(model.jnt_bodyid[j])))
        top = int(model.jnt_bodyid[j])
        geoms = np.array([c for c, g in enumerate(robot_geoms) if under(int(model.geom_bodyid[g]), top)], dtype=int)
        out.append(ArmLever(model.joint(j).name, float(d.xaxis[j][1]), geoms))
    return out


def lean_offsets(tr: Trajectory, rec: Recording, levers: list[ArmLever], trunk: np.ndarray,
                 plan_rows: int | None = None) -> tuple[np.ndarray, float] | None:
    """Shoulder pitch offsets per row [rad] that lean the torso as ``tr.root`` (the library) does.

    Where the recording has the body propped on an arm and a foot (both touch the world, the
    ``trunk`` geoms (columns of the root body's geoms) do not), after the planned path
    (``plan_rows``: the join row), the lean error is the reference torso
    pitch (:func:`torso_pitch_rad` of ``tr.root``) minus the simulated one, clipped to
    LEAN_MAX_STEP_RAD; it is smoothed over LEAN_SMOOTH_S, held from the last row measured to the
    end, ramped in over SLOPE_RAMP_S before the first, and turned into ``-LEAN_GAIN * error * axis_y`` on each
    arm's shoulder pitch (the arm propped on the world turns the torso the other way).

    Returns:
        (offsets of shape (T, n) in ``tr.joint_names`` order, largest smoothed error [rad]), or
        None without reference rows or without a time propped on arms and feet.
    """
    if tr.root is None or not levers:
        return None
    contact = world_contact(rec)
    feet = contact[:, rec.foot_geoms].any(axis=1)
    arms = np.zeros(len(rec.t), dtype=bool)
    for lever in levers:
        if lever.geoms.size:
            arms |= contact[:, lever.geoms].any(axis=1)
    idx = np.clip(np.searchsorted(rec.t, tr.t), 0, len(rec.t) - 1)
    valid = (feet & arms & ~contact[:, trunk].any(axis=1))[idx] & (tr.t <= tr.duration_s)
    valid[: plan_rows if plan_rows is not None and plan_rows > 0 else 1] = False  # the plan's root is kinematic, not a lean to follow
    if valid.sum() < 2:
        return None
    ref = torso_pitch_rad(tr.root[:, 3:])
    sim = np.interp(tr.t, rec.t, np.unwrap(torso_pitch_rad(rec.root_pose[:, 3:])))
    err = np.clip(np.angle(np.exp(1j * (ref - sim))), -LEAN_MAX_STEP_RAD, LEAN_MAX_STEP_RAD)
    tv, ev = tr.t[valid], err[valid]
    w = np.exp(-(((tr.t[:, None] - tv[None, :]) / LEAN_SMOOTH_S) ** 2))
    near = w.sum(axis=1) > 1e-6
    smooth = np.interp(tr.t, tr.t[near], (w[near] @ ev) / w[near].sum(axis=1))
    smooth[tr.t > tv[-1]] = smooth[np.flatnonzero(valid)[-1]]
    smooth *= np.clip((tr.t - (tv[0] - SLOPE_RAMP_S)) / SLOPE_RAMP_S, 0.0, 1.0)
    smooth[0] = 0.0  # the first row is where the robot lies
    off = np.zeros_like(tr.q)
    for lever in levers:
        off[:, tr.joint_names.index(lever.joint)] = -LEAN_GAIN * smooth * lever.axis_y
    return off, float(np.max(np.abs(smooth)))


def adapt_lean(
    robot: Robot, tr: Trajectory, rec: Recording, levers: list[ArmLever], trunk: np.ndarray, total: np.ndarray, plan_rows: int | None = None
) -> tuple[Trajectory, np.ndarray, float] | None:
    """``tr`` with :func:`lean_offsets` added (the total clipped to LEAN_MAX_OFFSET_RAD and the
    joint limits); None when the lean already matches within LEAN_MIN_RAD."""
    got = lean_offsets(tr, rec, levers, trunk, plan_rows)
    if got is None or got[1] < LEAN_MIN_RAD:
        return None
    new_total = np.clip(total + got[0], -LEAN_MAX_OFFSET_RAD, LEAN_MAX_OFFSET_RAD)
    cols = [robot.joint_index(n) for n in tr.joint_names]
    q = np.clip(tr.q + (new_total - total), robot.joint_lower[cols], robot.joint_upper[cols])
    return Trajectory(tr.robot, tr.joint_names, tr.t, q, tr.start, tr.report, tr.root), new_total, got[1]
