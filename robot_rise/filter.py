"""The dynamics filter: turn a planned path + library motion into servo targets proven in MuJoCo.

Paper 000 section 4.3 tracks the smoothed plan in a physics engine and connects it to the
database motion at the most similar frame with blending. A robot has no root actuation and its
strength is its servos', so here the "tracking controller" is the servo model itself (the
targets ARE what the servos receive) and the filter reshapes the targets, never the physics:

1. join the planned path to the library motion from the connecting frame on, blending the
   targets over ``blend_s`` around the join (000 section 4.3);
2. play it through the servo model (robot_rise.sim.player) from the start posture;
3. find violations: torque beyond (1 - margin) of the torque-speed envelope (dissertation 003
   eq. 2.2 strength limits; for us the DC-motor envelope), ZMP outside the support polygon while
   on the feet (003 eq. 2.11-2.14), the motion diverging from the plan (tracking error beyond
   the servo's saturation for longer than ``divergence_hold_s``: a roll that does not happen, a
   limb blocked), and finally the standing judge;
4. reshape: slow the offending windows down (time scaling, 003 eq. 2.9-2.10's comfort control
   does this by lowering speed where torque exceeds the limit); when the judge fails with no
   local violation, slow the motion after the join; on sloped ground (paper 000 section 5.2's
   10 deg slope) the library's flat-ground stance is first turned to the slope: from the moment
   the robot is on its feet the ankles take up the ground's tilt and the legs' lengths its
   difference across the feet, in the heading the robot really stands in
   (:func:`slope_stance_offsets`), so the body above them stays vertical; a body of other
   proportions than the library's (paper 000 section 5.3, retargeting), propped on its arms and
   feet at another lean than the library motion, gets its shoulders' pitch offset until its
   torso leans as the library's did (:func:`lean_offsets`), so it comes onto its feet with its
   centre of mass over them;
5. iterate until everything passes or ``max_iterations`` is reached, then say why not.

The output trajectory holds the commanded targets (not the plan) and a report proving them.
"""

from __future__ import annotations

import hashlib
import logging
import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from robot_rise.sim.standing import StandVerdict, judge, supported_on_feet, world_contact
from robot_rise.model import Robot, model_index
from robot_rise.paths import scene_path
from robot_rise.posture import Posture, yaw_rad
from robot_rise.servo import servo_spec
from robot_rise.sim.player import Player, Recording
from robot_rise.trajectory import Trajectory
from robot_rise.validity import DEFAULT_CONTACT_TOLERANCE_M

__all__ = [
    "FilterSettings",
    "Violation",
    "FilterIteration",
    "FilterResult",
    "join_with_blend",
    "time_scale",
    "find_violations",
    "dynamics_filter",
    "prove",
    "scene_digest",
    "ModelError",
    "ROBUSTNESS_CHECKS",
    "stands_under",
    "describe_fall",
    "ground_tilt_vector",
    "ankle_joints",
    "slope_ankle_offsets",
    "slope_stance_offsets",
    "leg_joints",
    "SLOPE_MIN_RAD",
    "torso_pitch_rad",
    "lean_offsets",
]

log = logging.getLogger(__name__)

# Slope handling (paper 000 section 5.2, rising on a slope; ours: the stance is turned to the slope).
SLOPE_MIN_RAD = math.radians(1.0)  # ground tilts below this are treated as level
SLOPE_RAMP_S = 0.3  # the ankle offsets are ramped in over this long before the robot is on its feet [s]
SLOPE_MIN_FEET_S = 0.2  # "on its feet": only the feet touch the ground for at least this long [s]
SLOPE_LEG_JOINTS = 4  # joints per leg the slope stance adjusts, from the sole up (ankle roll, pitch, knee, hip pitch)
ANKLE_JOINTS = 2  # joints per leg that take up the ground's tilt, from the sole up (ankle roll, pitch)

# Retargeting (paper 000 section 5.3: a body with other proportions rises on the same library,
# the dynamics filter adapting the motion; ours: the posture is adapted, not only the timing).
# Propped on its arms, a body with longer arms or a longer torso than the library's holds its
# torso at another lean than the library motion did, and comes onto its feet with its centre of
# mass behind (or ahead of) them. While an arm and a foot both touch the world, each arm's
# shoulder pitch takes up the difference between the library's torso pitch (its simulated root)
# and the simulated one; the offset is kept to the end (released, the arm would push again).
LEAN_MIN_RAD = math.radians(3.0)  # smoothed lean errors below this are left alone
LEAN_MAX_STEP_RAD = math.radians(10.0)  # the lean error fed back per row and iteration is clipped to this
LEAN_GAIN = 1.5  # shoulder offset per radian of lean error (a propped arm turns the torso by about 0.55 of it: op3 x1.3 arms)
LEAN_MAX_OFFSET_RAD = 0.6  # total shoulder pitch offset at most [rad]
LEAN_SMOOTH_S = 0.15  # the lean error is smoothed with a Gaussian of this width [s]
LEAN_ITERATIONS = 4  # filter iterations that may adapt the lean (on top of max_iterations)
LEAN_MIN_AXIS = 0.7  # a shoulder pitch joint's axis is at least this much along the body's y axis


@dataclass(frozen=True)
class FilterSettings:
    """Tuning of the dynamics filter.

    Attributes:
        envelope_margin: torque may use at most (1 - margin) of the torque-speed envelope
            (issue 6 default 10 %).
        self_penetration_tolerance_m: self contact deeper than this is a collision; shallower
            is touching (the validity checker's tolerance, so planner and filter agree).
        min_zmp_margin_m: the ZMP must stay this far inside the support polygon while on feet [m].
        balance_tolerance_m: ZMP excursions shallower than this are estimation noise (point-mass
            ZMP, support polygon from discrete contact points) [m].
        balance_hold_s: a ZMP excursion counts when it lasts this long [s] (impacts at touchdown
            are instantaneous and not a loss of balance).
        soft_iterations: extra iterations spent on balance/divergence violations once the motion
            is proven (stands, within the envelope); the best proven motion is kept.
        divergence_rad: tracking error counted as divergence [rad] (default 1.5 x the servo's
            saturation error: beyond saturation the servo pushes with all it has).
        divergence_hold_s: how long the error must last to count [s].
        slow_factor: time stretch applied to an offending window per iteration.
        window_pad_s: padding around an offending window [s].
        blend_s: blend duration around the plan-motion join [s].
        max_iterations: filter iterations before giving up.
        hold_s: time the final targets are held while the judge watches [s].
        max_duration_s: never stretch the motion beyond this [s].
    """

    envelope_margin: float = 0.10
    self_penetration_tolerance_m: float = DEFAULT_CONTACT_TOLERANCE_M
    min_zmp_margin_m: float = 0.0
    balance_tolerance_m: float = 0.005
    balance_hold_s: float = 0.1
    soft_iterations: int = 2
    divergence_rad: float = 0.33
    divergence_hold_s: float = 0.4
    slow_factor: float = 1.6
    window_pad_s: float = 0.15
    blend_s: float = 0.3
    max_iterations: int = 6
    hold_s: float = 3.0
    max_duration_s: float = 30.0


@dataclass(frozen=True)
class Violation:
    """One offending window of the played motion. Times on the trajectory's clock [s]."""

    kind: str  # "torque" | "balance" | "divergence" | "fall"
    t_start_s: float
    t_end_s: float
    joints: tuple[str, ...] = ()
    value: float = float("nan")

    def describe(self) -> str:
        where = f" ({', '.join(self.joints)})" if self.joints else ""
        return f"{self.kind}{where} at {self.t_start_s:.2f}-{self.t_end_s:.2f} s, value {self.value:.3f}"


@dataclass(frozen=True)
class FilterIteration:
    """What one iteration saw."""

    iteration: int
    duration_s: float
    peak_envelope_ratio: float
    standing: bool
    violations: tuple[str, ...]


@dataclass(frozen=True)
class FilterResult:
    """Outcome of the filter: the commanded trajectory (with its proof report) and the evidence."""

    ok: bool
    trajectory: Trajectory
    recording: Recording
    verdict: StandVerdict
    iterations: tuple[FilterIteration, ...]
    reason: str = ""
    report: dict[str, Any] = field(default_factory=dict)


def join_with_blend(plan: Trajectory, motion: Trajectory, frame: int, *, blend_s: float = 0.3, max_speed_rad_s: float = 2.0) -> Trajectory:
    """Plan (lying -> connecting posture) followed by the motion from ``frame`` on.

    The plan ends at (or near) the motion's frame ``frame``. The motion's rows from that frame
    are appended, shifted in time so that the transition from the plan's last row to the
    motion's frame takes at least ``blend_s`` and no joint moves faster than
    ``max_speed_rad_s`` across it: the servos' targets interpolate linearly between them, so a
    mismatch at the join becomes a short blend rather than a step (paper 000 section 4.3).

    Returns:
        a trajectory with the plan's start posture and joint order; its ``root`` rows are the
        plan's then the motion's (the library's simulated root) when both have them.
    """
    names = plan.joint_names
    cols = [motion.joint_names.index(j) for j in names]
    mq = motion.q[frame:, cols]
    mt = motion.t[frame:] - motion.t[frame]
    if len(mt) == 0:
        return plan
    gap = max(blend_s, float(np.max(np.abs(plan.q[-1] - mq[0]))) / max_speed_rad_s)
    t = np.concatenate([plan.t, plan.t[-1] + gap + mt])
    q = np.concatenate([plan.q, mq])
    # the planned root, then the library's simulated one: the lean the filter adapts the body to
    root = np.concatenate([plan.root, motion.root[frame:]]) if plan.root is not None and motion.root is not None else None
    return Trajectory(plan.robot, names, t, q, plan.start, dict(plan.report), root)


def time_scale(tr: Trajectory, windows: list[tuple[float, float]], factor: float) -> Trajectory:
    """Stretch time by ``factor`` inside ``windows`` (trajectory clock, seconds); rows unchanged."""
    if not windows:
        return tr
    t = tr.t
    dt = np.diff(t)
    mid = (t[:-1] + t[1:]) / 2
    scale = np.ones_like(dt)
    for a, b in windows:
        scale[(mid >= a) & (mid <= b)] = factor
    new_t = np.concatenate([[0.0], np.cumsum(dt * scale)])
    return Trajectory(tr.robot, tr.joint_names, new_t, tr.q, tr.start, tr.report, tr.root)


def _windows(mask: np.ndarray, t: np.ndarray, min_len_s: float = 0.0) -> list[tuple[int, int]]:
    """Index ranges [i, j] of contiguous True runs lasting at least min_len_s."""
    out = []
    i = 0
    n = len(mask)
    while i < n:
        if mask[i]:
            j = i
            while j + 1 < n and mask[j + 1]:
                j += 1
            if t[j] - t[i] >= min_len_s - 1e-9:
                out.append((i, j))
            i = j + 1
        else:
            i += 1
    return out


def find_violations(rec: Recording, settings: FilterSettings, *, saturation_rad: float) -> list[Violation]:
    """Violations in a recording (times on the recording's clock = the trajectory's)."""
    out: list[Violation] = []
    t = rec.t
    limit = 1.0 - settings.envelope_margin
    over = rec.envelope_ratio > limit
    for i, j in _windows(over.any(axis=1), t):
        joints = tuple(rec.joint_names[k] for k in np.flatnonzero(over[i : j + 1].any(axis=0)))
        out.append(Violation("torque", float(t[i]), float(t[j]), joints, float(rec.envelope_ratio[i : j + 1].max())))
    on = supported_on_feet(rec) & np.isfinite(rec.zmp_margin_m)
    bad = on & (np.nan_to_num(rec.zmp_margin_m, nan=1.0) < settings.min_zmp_margin_m - settings.balance_tolerance_m)
    for i, j in _windows(bad, t, settings.balance_hold_s):
        out.append(Violation("balance", float(t[i]), float(t[j]), (), float(np.nanmin(rec.zmp_margin_m[i : j + 1]))))
    err = np.abs(rec.q - rec.goal)
    div = err > max(settings.divergence_rad, 1.5 * saturation_rad)
    for i, j in _windows(div.any(axis=1), t, settings.divergence_hold_s):
        joints = tuple(rec.joint_names[k] for k in np.flatnonzero(div[i : j + 1].any(axis=0)))
        out.append(Violation("divergence", float(t[i]), float(t[j]), joints, float(err[i : j + 1].max())))
    return out


def scene_digest(scene: str | os.PathLike[str] | None) -> str:
    """SHA-256 of the scene file ('' for no scene)."""
    if scene is None:
        return ""
    return hashlib.sha256(scene_path(scene).read_bytes()).hexdigest()


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


def _stand_facing_x(robot: Robot, model: mujoco.MjModel) -> mujoco.MjData:
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
    d = _stand_facing_x(robot, model)
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


def _feet_stretches(rec: Recording) -> list[tuple[int, int]]:
    """Sample ranges [i, j] "on its feet": only the feet touch the world for at least SLOPE_MIN_FEET_S."""
    if len(rec.t) < 2:
        return []
    need = max(1, int(round(SLOPE_MIN_FEET_S / float(rec.t[1] - rec.t[0]))))
    return [(i, j) for i, j in _windows(supported_on_feet(rec), rec.t) if j - i + 1 >= need]


def _feet_from(rec: Recording, until_s: float) -> int | None:
    """First sample (at most ``until_s``) from which the robot is on its feet (:func:`_feet_stretches`)."""
    stretches = _feet_stretches(rec)
    return stretches[0][0] if stretches and rec.t[stretches[0][0]] <= until_s else None


def _turn_stance_to_slope(
    robot: Robot, tr: Trajectory, rec: Recording, model: mujoco.MjModel, tilt_world: np.ndarray
) -> tuple[Trajectory, dict[str, Any]] | None:
    """``tr`` with the leg offsets of :func:`slope_stance_offsets` (for its final stance) from when
    the robot is on its feet (ramped in over SLOPE_RAMP_S before), in the heading it stood in on
    ``rec``; None if it never was."""
    k = _feet_from(rec, tr.duration_s)
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
class _ArmLever:
    """An arm's shoulder pitch joint, the y component of its axis, and the arm's geoms (columns)."""

    joint: str
    axis_y: float
    geoms: np.ndarray


def shoulder_pitch_joints(robot: Robot, model: mujoco.MjModel) -> dict[str, float]:
    """Each arm's shoulder pitch joint -> the y component of its axis in the torso's frame [unit].

    Arms are the limbs named ``*arm*`` in robot.toml; of an arm's hinges, the one nearest the
    torso whose axis (``stand`` keyframe) is at least LEAN_MIN_AXIS along the torso's y axis.
    With the arm propped on the world, turning it by ``-lean * y`` leans the torso forward by
    about ``lean``. Not exported: what ``dynamics_filter`` adapts (its ``lean_adapted`` report), as
    a name-to-axis view for tests.
    """
    return {a.joint: a.axis_y for a in _arm_levers(robot, model, np.zeros(0, dtype=int))}


def _arm_levers(robot: Robot, model: mujoco.MjModel, robot_geoms: np.ndarray) -> list[_ArmLever]:
    d = _stand_facing_x(robot, model)

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
        out.append(_ArmLever(model.joint(j).name, float(d.xaxis[j][1]), geoms))
    return out


def lean_offsets(tr: Trajectory, rec: Recording, levers: list[_ArmLever], trunk: np.ndarray) -> tuple[np.ndarray, float] | None:
    """Shoulder pitch offsets per row [rad] that lean the torso as ``tr.root`` (the library) does.

    Where the recording has the body propped on an arm and a foot (both touch the world, the
    ``trunk`` geoms (columns of the root body's geoms) do not), after the planned path
    (``report["plan_rows"]``), the lean error is the reference torso
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
    rows = tr.report.get("plan_rows")
    valid[: rows if isinstance(rows, int) and rows > 0 else 1] = False  # the plan's root is kinematic, not a lean to follow
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


def _adapt_lean(
    robot: Robot, tr: Trajectory, rec: Recording, levers: list[_ArmLever], trunk: np.ndarray, total: np.ndarray
) -> tuple[Trajectory, np.ndarray, float] | None:
    """``tr`` with :func:`lean_offsets` added (the total clipped to LEAN_MAX_OFFSET_RAD and the
    joint limits); None when the lean already matches within LEAN_MIN_RAD."""
    got = lean_offsets(tr, rec, levers, trunk)
    if got is None or got[1] < LEAN_MIN_RAD:
        return None
    new_total = np.clip(total + got[0], -LEAN_MAX_OFFSET_RAD, LEAN_MAX_OFFSET_RAD)
    cols = [robot.joint_index(n) for n in tr.joint_names]
    q = np.clip(tr.q + (new_total - total), robot.joint_lower[cols], robot.joint_upper[cols])
    return Trajectory(tr.robot, tr.joint_names, tr.t, q, tr.start, tr.report, tr.root), new_total, got[1]


def _segment_at(trajectory: Trajectory, t_s: float) -> str:
    """Which part of a rise trajectory ``t_s`` falls in: the planned path or the library motion."""
    rep = trajectory.report
    rows = rep.get("plan_rows")
    if not isinstance(rows, int) or not 0 < rows < len(trajectory.t):
        return f"at {t_s:.2f} s"
    join = float(trajectory.t[rows])
    if t_s < float(trajectory.t[rows - 1]):
        return f"at {t_s:.2f} s, in the planned path (ends {trajectory.t[rows - 1]:.2f} s)"
    if t_s < join:
        return f"at {t_s:.2f} s, in the blend into {rep.get('motion', 'the library motion')}"
    if t_s > trajectory.duration_s:
        return f"at {t_s:.2f} s, in the final hold"
    return f"at {t_s:.2f} s, {t_s - join:.2f} s into {rep.get('motion', 'the library motion')} (from frame {rep.get('connecting_frame', '?')})"


def describe_fall(rec: Recording, trajectory: Trajectory, violations: list[Violation]) -> str:
    """Why a played motion did not end standing: when, in which segment, and the constraint broken.

    "on its feet" = only the feet touch the ground (the judge's condition). Reported: whether and
    when the robot got onto its feet, when it left them, the highest torso reached, and the
    violation (balance = ZMP outside the support polygon, paper 003 eq. 2.13-2.14; divergence =
    a joint that could not follow its target; torque) nearest before that moment.
    """
    if len(rec.t) == 0:
        return "nothing played"
    h = rec.torso_height_m / rec.stand_height_m
    k_hi = int(np.argmax(h))
    stretches = _feet_stretches(rec)
    parts: list[str] = []
    t_ref: float
    if not stretches:
        t_ref = float(rec.t[k_hi])
        from robot_rise.sampling import classify_lying

        parts.append(
            f"never on its feet alone for {SLOPE_MIN_FEET_S:.1f} s; highest torso {100 * h[k_hi]:.0f} % of stand height "
            + _segment_at(trajectory, t_ref)
            + f"; ended lying {classify_lying(rec.root_pose[-1, 3:])}"
        )
    else:
        first, last = stretches[-1]
        t_ref = float(rec.t[last])
        after = min(last + 1, len(rec.t) - 1)
        touching = [rec.robot_geom_names[g] for g in np.flatnonzero(world_contact(rec)[after])]
        parts.append(
            f"on its feet {_segment_at(trajectory, float(rec.t[first]))} until {rec.t[last]:.2f} s (torso tilt then "
            f"{np.degrees(rec.tilt_rad[last]):.0f} deg, highest torso {100 * h[k_hi]:.0f} % of stand height), then "
            + (
                ("touching the world with " + ", ".join(touching) if touching else "in the air (nothing touches)")
                if last + 1 < len(rec.t)
                else "the recording ended"
            )
        )
    t_fail = t_ref if stretches else float(rec.t[-1])  # never on its feet: the whole play counts
    pressed = [(a, b, t) for a, b, t in rec.obstacle_contact_pairs if t <= t_fail + 0.05]
    if pressed:
        parts.append("touched the scene's obstacles: " + ", ".join(f"{a}/{b} from {t:.2f} s" for a, b, t in pressed[:4]))
    before = [v for v in violations if v.t_start_s <= t_fail + 0.05]
    if before:
        # a fall from the feet: the violation just before it; never up: the first thing that went wrong
        v = max(before, key=lambda v: (v.t_end_s, v.kind == "balance")) if stretches else min(before, key=lambda v: v.t_start_s)
        what = {
            "balance": f"ZMP outside the support polygon by {-1000 * v.value:.0f} mm",
            "divergence": f"joints could not follow their targets ({', '.join(v.joints[:4])}, error {v.value:.2f} rad)",
            "torque": f"torque {v.value:.2f} of the envelope ({', '.join(v.joints[:4])})",
        }.get(v.kind, v.describe())
        parts.append(f"{'last' if stretches else 'first'} violation: {what} {_segment_at(trajectory, v.t_start_s)} to {v.t_end_s:.2f} s")
    return "; ".join(parts)


def prove(
    robot: Robot,
    trajectory: Trajectory,
    *,
    scene: str | os.PathLike[str] | None = "flat",
    settings: FilterSettings = FilterSettings(),
    player: Player | None = None,
    start: Posture | None = None,
) -> tuple[Recording, StandVerdict, dict[str, Any]]:
    """Replay a trajectory from its start posture and report the verdict and limits.

    Returns:
        (recording, verdict, report) where report["proven"] is True only if the robot stands
        by the judge, torque stays within (1 - margin) of the envelope at every physics step,
        and no self-collision occurred.
    """
    rec, verdict, report, _ = _prove(
        robot, trajectory, scene=scene, settings=settings, player=player or Player(robot, scene), start=start,
        saturation_rad=_saturation_rad(robot), want_violations=False,
    )
    return rec, verdict, report


def _saturation_rad(robot: Robot) -> float:
    """The smallest saturation error of the robot's servos [rad] (the divergence floor of find_violations)."""
    return min(servo_spec(sv.model).saturation_error_rad() for sv in robot.servos)


def _prove(
    robot: Robot,
    trajectory: Trajectory,
    *,
    scene: str | os.PathLike[str] | None,
    settings: FilterSettings,
    player: Player,
    start: Posture | None,
    saturation_rad: float,
    want_violations: bool = True,
) -> tuple[Recording, StandVerdict, dict[str, Any], list[Violation]]:
    """:func:`prove`, also returning the recording's violations (:func:`find_violations`, all of
    them; found only for a fall's diagnosis unless ``want_violations``: the filter reshapes them)."""
    rec = player.play(trajectory, start, hold_s=settings.hold_s)
    verdict = judge(rec)
    limit = 1.0 - settings.envelope_margin
    peak_per_joint = rec.envelope_ratio.max(axis=0)
    on = supported_on_feet(rec) & np.isfinite(rec.zmp_margin_m)
    ground_geoms = [rec.robot_geom_names[g] for g in np.flatnonzero(rec.ground_contact.any(axis=0))]
    within = verdict.peak_envelope_ratio <= limit + 1e-9
    # Touching is not colliding: a limb resting on another (as a lying robot's often does from
    # the start) interpenetrates less than the validity checker's contact tolerance.
    self_collision = bool(np.max(rec.self_penetration_m, initial=0.0) > settings.self_penetration_tolerance_m)
    proven = bool(verdict.standing and within and not self_collision)
    problems = []
    diagnosis = ""
    violations = (find_violations(rec, settings, saturation_rad=saturation_rad)
                  if want_violations or not verdict.standing else [])
    if not verdict.standing:
        diagnosis = describe_fall(rec, trajectory, violations)
        problems.append(f"not standing: {verdict.reason} ({diagnosis})")
    if not within:
        worst = rec.joint_names[int(np.argmax(peak_per_joint))]
        problems.append(f"torque {verdict.peak_envelope_ratio:.2f} of the envelope (limit {limit:.2f}) at {worst}")
    if self_collision:
        k_self = int(np.argmax(rec.self_penetration_m))
        problems.append(
            f"self-collision {1000 * float(np.max(rec.self_penetration_m)):.1f} mm deep {_segment_at(trajectory, float(rec.t[k_self]))}: "
            + ", ".join(f"{a}/{b}" for a, b in rec.self_contact_pairs[:3])
        )
    report = {
        "proven": proven,
        "problems": problems,
        "robot": robot.name,
        "robot_digest": robot.digest(),
        "scene": str(scene) if scene is not None else None,
        "scene_digest": scene_digest(scene),
        "standing": verdict.standing,
        "judge": verdict.summary(),
        "duration_s": float(trajectory.duration_s),
        "peak_torque_ratio": float(verdict.peak_envelope_ratio),
        "envelope_limit": limit,
        "peak_torque_ratio_per_joint": {j: float(r) for j, r in zip(rec.joint_names, peak_per_joint)},
        "min_zmp_margin_m": float(np.min(rec.zmp_margin_m[on])) if on.any() else None,
        "time_on_feet_s": float(on.sum() * (rec.t[1] - rec.t[0])) if len(rec.t) > 1 else 0.0,
        "ground_contacts": ground_geoms,
        "self_collision": self_collision,
        "self_touch": bool(verdict.self_collision),
        "max_self_penetration_m": float(np.max(rec.self_penetration_m, initial=0.0)),
        "stood_from_s": float(verdict.stood_from_s) if np.isfinite(verdict.stood_from_s) else None,
        **({"diagnosis": diagnosis} if diagnosis else {}),
    }
    return rec, verdict, report, violations


def dynamics_filter(
    robot: Robot,
    commanded: Trajectory,
    *,
    scene: str | os.PathLike[str] | None = "flat",
    settings: FilterSettings = FilterSettings(),
    start: Posture | None = None,
    protect_until_s: float = 0.0,
    progress: Callable[[int, int], None] | None = None,
) -> FilterResult:
    """Reshape ``commanded`` until it stands the robot up within the servo limits, or say why not.

    Args:
        robot: the robot.
        commanded: first guess of the servo targets (e.g. join_with_blend(plan, motion, frame)).
        scene: scene the motion is proven in.
        settings: filter tuning.
        start: the posture the robot really lies in (default: commanded.start).
        protect_until_s: never stretch before this time (e.g. to keep a key posture's timing).
        progress: called as progress(iteration, max_iterations).

    Returns:
        FilterResult whose trajectory holds the final commanded targets and the proof report.
    """
    start = start or commanded.start
    player = Player(robot, scene)
    saturation = _saturation_rad(robot)
    current = commanded
    history: list[FilterIteration] = []
    best: tuple[Trajectory, Recording, StandVerdict, dict[str, Any]] | None = None  # best proven so far
    last: tuple[Trajectory, Recording, StandVerdict, dict[str, Any]] | None = None
    soft = 0
    tilt = ground_tilt_vector(player.model, player.index.ground_geoms)
    slope_pending = float(np.linalg.norm(tilt)) >= SLOPE_MIN_RAD
    slope_info: dict[str, Any] | None = None
    levers = _arm_levers(robot, player.model, player.index.robot_geoms)
    trunk = np.flatnonzero(player.model.geom_bodyid[player.index.robot_geoms] == player.index.root_body)
    lean_total = np.zeros_like(current.q)
    lean_used = 0  # lean adaptations so far (at most LEAN_ITERATIONS); each one earns an extra iteration
    lean_info: dict[str, Any] | None = None
    it = 0
    while it < settings.max_iterations + lean_used:
        it += 1
        rec, verdict, report, found = _prove(robot, current, scene=scene, settings=settings, player=player, start=start, saturation_rad=saturation)
        if slope_pending and not report["proven"]:
            # flat-ground stance on a slope: turn it to the slope once, in the heading the robot stood in
            slope_pending = False
            turned = _turn_stance_to_slope(robot, current, rec, player.model, tilt)
            if turned is not None:
                history.append(FilterIteration(it, current.duration_s, verdict.peak_envelope_ratio, verdict.standing, ("stance turned to the slope",)))
                log.info("filter iteration %d: stance turned to the slope: %s", it, turned[1])
                last = (current, rec, verdict, report)
                current, slope_info = turned
                continue
        violations = [v for v in found if v.t_start_s <= current.duration_s]
        if lean_used < LEAN_ITERATIONS and not verdict.standing and current.root is not None and not any(v.kind == "torque" for v in violations):
            # torque first (time scaling changes how the body moves); then a lean other than the library's on arms and feet
            adapted = _adapt_lean(robot, current, rec, levers, trunk, lean_total)
            if adapted is not None:
                lean_used += 1
                history.append(FilterIteration(it, current.duration_s, verdict.peak_envelope_ratio, verdict.standing, (f"lean on arms and feet adapted (error {math.degrees(adapted[2]):.1f} deg)",)))
                log.info("filter iteration %d: lean on arms and feet adapted, error %.1f deg", it, math.degrees(adapted[2]))
                last = (current, rec, verdict, report)
                current, lean_total = adapted[0], adapted[1]
                lean_info = {"shoulder_joints": [lv.joint for lv in levers], "max_offset_rad": float(np.max(np.abs(lean_total))), "iterations": lean_used}
                continue
        history.append(
            FilterIteration(it, current.duration_s, verdict.peak_envelope_ratio, verdict.standing, tuple(v.describe() for v in violations))
        )
        log.info("filter iteration %d: %s; %d violations", it, verdict.summary(), len(violations))
        if progress is not None:
            progress(it, settings.max_iterations)
        last = (current, rec, verdict, report)
        if report["proven"]:
            if best is None or len(violations) < best[3].get("_n_violations", 1 << 30):
                best = (current, rec, verdict, {**report, "_n_violations": len(violations)})
            if not violations:
                break
            soft += 1
            if soft > settings.soft_iterations:
                break
        windows = [
            (max(v.t_start_s - settings.window_pad_s, protect_until_s), min(v.t_end_s + settings.window_pad_s, current.duration_s))
            for v in violations
        ]
        windows = [(a, b) for a, b in windows if b > a]
        if not windows and not report["proven"]:
            # failed without a local cause: slow down everything after the protected part
            windows = [(protect_until_s, current.duration_s)]
        if not windows:
            break
        stretched = time_scale(current, windows, settings.slow_factor)
        if stretched.duration_s > settings.max_duration_s:
            break
        current = stretched
    assert last is not None
    current, rec, verdict, report = best if best is not None else last
    report = {k: v for k, v in report.items() if not k.startswith("_")}
    ok = bool(report["proven"])
    reason = "" if ok else "; ".join(report["problems"]) + (f" (after {len(history)} filter iterations)")
    full_report = {
        **report,
        **({"slope_stance": slope_info} if slope_info is not None else {}),
        **({"lean_adapted": lean_info} if lean_info is not None else {}),
        "filter_iterations": len(history),
        "filter_history": [
            {"iteration": h.iteration, "duration_s": h.duration_s, "peak_torque_ratio": h.peak_envelope_ratio, "standing": h.standing, "violations": list(h.violations)}
            for h in history
        ],
    }
    final = Trajectory(robot.name, current.joint_names, current.t, current.q, start, {**current.report, **full_report}, None)
    return FilterResult(ok, final, rec, verdict, tuple(history), reason, full_report)


@dataclass(frozen=True)
class ModelError:
    """A deliberate error between the proof's model and the real robot, for robustness replays.

    Attributes:
        label: what it is, for reports.
        mass_scale: every body's mass and inertia times this.
        friction_scale: every geom's sliding friction times this.
        voltage_scale: servo supply voltage times this (stall torque and no-load speed scale with it).
        latency_s: the targets arrive this much later.
    """

    label: str
    mass_scale: float = 1.0
    friction_scale: float = 1.0
    voltage_scale: float = 1.0
    latency_s: float = 0.0


# Checked by ``rise`` on every proven candidate (ours: a heavy, grippy robot whose commands arrive
# one 100 Hz control period late — a nominal proof that is a fluke of exact timing fails this).
ROBUSTNESS_CHECKS: tuple[ModelError, ...] = (
    ModelError("mass +10 %, friction x1.33, 10 ms latency", mass_scale=1.1, friction_scale=1.2 / 0.9, latency_s=0.01),
)


def stands_under(
    robot: Robot,
    trajectory: Trajectory,
    error: ModelError,
    *,
    scene: str | os.PathLike[str] | None = "flat",
    settings: FilterSettings = FilterSettings(),
    start: Posture | None = None,
) -> bool:
    """Replay ``trajectory`` unchanged on a model with ``error``; True if the robot still stands
    (judge) with no self-collision beyond the tolerance. Torque is not re-checked: the model is
    deliberately wrong."""
    from robot_rise.model import SUPPLY_VOLTAGE_V

    player = Player(robot, scene, mass_scale=error.mass_scale, friction_scale=error.friction_scale, voltage_v=SUPPLY_VOLTAGE_V * error.voltage_scale)
    tr = trajectory
    if error.latency_s > 0:
        tr = Trajectory(tr.robot, tr.joint_names, np.concatenate([[0.0], tr.t + error.latency_s]), np.vstack([tr.q[:1], tr.q]), tr.start, tr.report)
    _, verdict, report = prove(robot, tr, scene=scene, settings=settings, player=player, start=start)
    return bool(verdict.standing and not report["self_collision"])
