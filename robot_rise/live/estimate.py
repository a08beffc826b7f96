"""Where the body lies: the whole posture from the joint angles and the IMU's gravity direction.

The servos know the joint angles; they cannot know how the body lies. The IMU on the root body
(the OP3's torso) knows which way is up in its own frame. Together they fix everything that
matters on flat ground:

1. Root orientation: the roll and pitch that turn the measured up direction (root frame) onto the
   world's up (:func:`root_quat_from_up`); yaw is free (0, or kept from a known heading), it
   does not matter on flat ground.
2. Root position: the model is placed with those angles and that orientation just above the
   ground and let settle, every joint held at its measured angle by servos a hundred times
   stiffer than the robot's (a rigid body of the measured shape, within a few mrad), until it
   is at rest: the contacts then match a body lying on the floor (a few millimetres, and the
   few degrees an IMU error leaves, settle out).

The settled orientation is the estimate's (``imu_change_deg`` says how far the settle turned it
from the IMU's up). A turn larger than an IMU's error can be means the model came to rest
elsewhere than the robot (a body propped on its side rolls onto its back): then the IMU's
orientation is kept and the body lowered onto the ground (``settled`` False). The joint angles of
the estimate are the measured ones, clamped into the joint limits.

When the truth is known (the physics twin), :func:`estimate_error` compares: orientation error
(the angle between the estimated and the true up directions, yaw-free), joint error and root
height error.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import mujoco
import numpy as np

from robot_rise.live.fall import LyingKind
from robot_rise.model import Robot, compose, model_index
from robot_rise.placement import lowest_point_at
from robot_rise.posture import Posture, posture_from_qpos
from robot_rise.sampling import classify_lying
from robot_rise.validity import ValidityChecker

__all__ = [
    "EstimateConfig",
    "EstimateError",
    "PostureEstimate",
    "PostureEstimator",
    "root_quat_from_up",
    "up_of_quat",
    "estimate_posture",
    "estimate_error",
]

log = logging.getLogger(__name__)

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class EstimateConfig:
    """How the estimate settles the model (ours; measured on the OP3 twin).

    Attributes:
        drop_clearance_m: [m] the lowest point starts this far above the ground: a drop this
            small leaves no bounce.
        settle_max_s: [s] simulated time at most; an estimate not at rest by then is returned
            with ``settled`` False (a body rocking on a ridge).
        settle_min_s: [s] never at rest before this.
        settle_hold_s: [s] the root must stay slow this long.
        settle_speed: "slow": every root velocity component below this [m/s, rad/s].
        lift_step_m: [m] an estimate that penetrates the ground deeper than the validity
            checker's tolerance is lifted in steps of this (at most ``max_lift_m``).
        max_lift_m: [m] see ``lift_step_m``.
        max_settle_turn_deg: [deg] the settle may turn the body this far from the IMU's up at
            most (an IMU's error is a degree or two); a larger turn means the model came to rest
            elsewhere than the robot (a body propped on its side on a few contacts rolls onto
            its back: 10-14 deg on 3 of 20 side-lying OP3 twins), so the IMU's orientation is
            kept and the body is lowered onto the ground instead.
    """

    drop_clearance_m: float = 0.001
    settle_max_s: float = 2.0
    settle_min_s: float = 0.2
    settle_hold_s: float = 0.1
    settle_speed: float = 0.01
    lift_step_m: float = 0.0005
    max_lift_m: float = 0.005
    max_settle_turn_deg: float = 5.0

    def __post_init__(self) -> None:
        for name in self.__dataclass_fields__:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"EstimateConfig.{name} must be finite and > 0, got {value}")


@dataclass(frozen=True)
class EstimateError:
    """An estimate against the truth.

    Attributes:
        orientation_deg: angle between the estimated and the true up direction in the root
            frame [deg] (roll and pitch error; yaw is free).
        joint_max_rad: largest joint angle error [rad].
        joint_rms_rad: root-mean-square joint angle error [rad].
        root_height_m: estimated minus true root height [m].
        imu_orientation_deg: the IMU's own up direction against the true one [deg], before the
            settle (NaN when not known).
    """

    orientation_deg: float
    joint_max_rad: float
    joint_rms_rad: float
    root_height_m: float
    imu_orientation_deg: float = math.nan

    def to_dict(self) -> dict[str, float]:
        return {"orientation_deg": self.orientation_deg, "joint_max_rad": self.joint_max_rad,
                "joint_rms_rad": self.joint_rms_rad, "root_height_m": self.root_height_m,
                "imu_orientation_deg": self.imu_orientation_deg}


@dataclass(frozen=True)
class PostureEstimate:
    """Where the body lies, as estimated.

    Attributes:
        posture: the estimated posture (measured joint angles, settled root pose).
        up_root: the IMU's up direction in the root frame (unit 3-vector) it started from.
        lying: the lying kind of the settled orientation (None: upright).
        imu_change_deg: angle by which the settle turned the root away from the IMU's up [deg].
        settled: the model came to rest within ``settle_max_s``, within ``max_settle_turn_deg``
            of the IMU's up (else the IMU's orientation is kept, lowered onto the ground).
        settle_s: simulated settling time [s].
        valid: the posture passes the scene's validity checker (touching allowed).
        error: against the truth, when one was given (else None).
    """

    posture: Posture
    up_root: Vec3
    lying: LyingKind | None
    imu_change_deg: float
    settled: bool
    settle_s: float
    valid: bool
    error: EstimateError | None = None


def _unit(v: Sequence[float]) -> np.ndarray:
    a = np.asarray(v, dtype=float).reshape(3)
    n = float(np.linalg.norm(a))
    if not (math.isfinite(n) and n > 0.0):
        raise ValueError(f"the up direction must be a finite non-zero 3-vector, got {tuple(v)!r}")
    return a / n


def root_quat_from_up(up_root: Sequence[float], yaw_rad: float = 0.0) -> np.ndarray:
    """The root orientation (w, x, y, z) whose up direction seen in the root frame is ``up_root``.

    Z-Y-X Euler angles: the up direction in the root frame of R = Rz(yaw) Ry(pitch) Rx(roll) is
    ``R^T e_z = (-sin p, cos p sin r, cos p cos r)``, so roll = atan2(u_y, u_z) and pitch =
    atan2(-u_x, hypot(u_y, u_z)); yaw is a free heading.

    Args:
        up_root: up (against gravity) in the root frame, any length > 0, 3 values.
        yaw_rad: heading [rad].

    Returns:
        unit quaternion (w, x, y, z), shape (4,).

    Raises:
        ValueError: ``up_root`` is zero or not finite.
    """
    u = _unit(up_root)
    roll = math.atan2(u[1], u[2])
    pitch = math.atan2(-u[0], math.hypot(u[1], u[2]))
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw_rad / 2), math.sin(yaw_rad / 2)
    q = np.array([cy * cp * cr + sy * sp * sr, cy * cp * sr - sy * sp * cr,
                  cy * sp * cr + sy * cp * sr, sy * cp * cr - cy * sp * sr])
    return q / np.linalg.norm(q)


def up_of_quat(quat_wxyz: Sequence[float]) -> np.ndarray:
    """The world's up direction seen in the body frame of orientation ``quat_wxyz``: R^T e_z."""
    w, x, y, z = (float(v) for v in quat_wxyz)
    u = np.array([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)])
    return u / np.linalg.norm(u)


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return math.degrees(math.acos(max(-1.0, min(1.0, float(a @ b)))))


def estimate_error(estimate: Posture, truth: Posture, robot: Robot) -> EstimateError:
    """``estimate`` against ``truth`` (same robot): orientation (yaw-free), joints, root height."""
    names = robot.joint_names
    dq = estimate.joint_vector(names) - truth.joint_vector(names)
    return EstimateError(
        orientation_deg=_angle_deg(up_of_quat(estimate.root_quat_wxyz), up_of_quat(truth.root_quat_wxyz)),
        joint_max_rad=float(np.max(np.abs(dq))) if dq.size else 0.0,
        joint_rms_rad=float(np.sqrt(np.mean(dq * dq))) if dq.size else 0.0,
        root_height_m=float(estimate.root_pos[2] - truth.root_pos[2]),
    )


# The settling model's servos are this many times stiffer than the robot's (position gain, torque
# limit, and, so that the loop keeps its damping ratio and stays stable at the 2 ms step, rotor
# inertia and damping too): the body holds the measured angles within a few mrad under its own
# weight (the XM430 model sags up to ~0.2 rad), as a rigid body of the measured shape. Ours.
STIFFNESS_FACTOR = 100.0


def _stiffen_servos(m: mujoco.MjModel, actuators: np.ndarray, dofs: np.ndarray, factor: float) -> None:
    m.actuator_gainprm[actuators, 0] *= factor
    m.actuator_biasprm[actuators, 1] *= factor
    m.actuator_forcerange[actuators] *= factor
    m.dof_armature[dofs] *= factor
    m.dof_damping[dofs] *= factor


class PostureEstimator:
    """Estimates lying postures of one robot in one scene (build once per robot, reuse).

    Args:
        robot: the robot.
        scene: the scene it lies in (default flat ground).
        config: settling settings.

    Not thread-safe (owns one MjData).
    """

    def __init__(self, robot: Robot, scene: str | os.PathLike[str] | None = "flat", *,
                 config: EstimateConfig | None = None, checker: ValidityChecker | None = None) -> None:
        self.robot = robot
        self.scene = scene
        self.config = config or EstimateConfig()
        self.model = compose(robot, scene, with_actuators=True)
        self.data = mujoco.MjData(self.model)
        self.index = model_index(self.model, robot)
        _stiffen_servos(self.model, self.index.actuators, self.index.dof_joints, STIFFNESS_FACTOR)
        self.checker = checker if checker is not None else ValidityChecker(robot, scene)

    def estimate(self, joints_rad: Mapping[str, float], up_root: Sequence[float], *, yaw_rad: float = 0.0,
                 xy_m: Sequence[float] = (0.0, 0.0), truth: Posture | None = None) -> PostureEstimate:
        """Estimate the lying posture.

        Args:
            joints_rad: measured joint angles by joint name [rad] (one sync read); joints not
                given keep the stand keyframe's angle; values are clamped into the joint limits.
            up_root: up direction in the root frame (the accelerometer at rest, or the fall
                detector's gravity estimate), 3 values, any length > 0.
            yaw_rad: heading of the estimate [rad] (free on flat ground).
            xy_m: root position on the ground [m] (free on flat ground).
            truth: the true posture, when known (the twin): fills ``error``.

        Raises:
            ValueError: ``up_root`` is zero or not finite; a joint angle is not finite.
        """
        robot, m, idx, cfg = self.robot, self.model, self.index, self.config
        up = _unit(up_root)
        q_joints = np.array(robot.stand_qpos[7:], dtype=float)
        for k, name in enumerate(robot.joint_names):
            if name in joints_rad:
                v = float(joints_rad[name])
                if not math.isfinite(v):
                    raise ValueError(f"joint {name}: angle {v} is not finite")
                q_joints[k] = v
        q_joints = np.clip(q_joints, robot.joint_lower, robot.joint_upper)
        qpos = m.qpos0.copy()
        qpos[idx.qpos_root[:3]] = [float(xy_m[0]), float(xy_m[1]), 1.0]
        qpos[idx.qpos_root[3:]] = root_quat_from_up(up, yaw_rad)
        qpos[idx.qpos_joints] = q_joints
        qpos = lowest_point_at(self.checker, qpos, cfg.drop_clearance_m)
        rest, settled, settle_s = self._settle(qpos, q_joints)
        rest[idx.qpos_root[3:]] /= np.linalg.norm(rest[idx.qpos_root[3:]])
        rest[idx.qpos_joints] = q_joints  # the measured angles (the stiff servos sag a few mrad)
        change = _angle_deg(up_of_quat(rest[idx.qpos_root[3:]]), up)
        if change > cfg.max_settle_turn_deg:  # rested elsewhere than the robot: keep the IMU's tilt
            log.info("posture estimate: the settle turned the body %.1f deg from the IMU's up; keeping the IMU's", change)
            rest = lowest_point_at(self.checker, qpos)
            settled = False
        rest, valid = self._lift_if_penetrating(rest)
        posture = posture_from_qpos(robot, idx, rest)
        kind = classify_lying(posture.root_quat_wxyz)
        error = None
        if truth is not None:
            error = replace(estimate_error(posture, truth, robot),
                            imu_orientation_deg=_angle_deg(up, up_of_quat(truth.root_quat_wxyz)))
        if not settled and change <= cfg.max_settle_turn_deg:
            log.warning("posture estimate not at rest after %.1f s of settling", settle_s)
        return PostureEstimate(posture, (float(up[0]), float(up[1]), float(up[2])),
                               None if kind == "upright" else kind,  # type: ignore[arg-type]
                               change, settled, settle_s, valid, error)

    def _settle(self, qpos: np.ndarray, q_joints: np.ndarray) -> tuple[np.ndarray, bool, float]:
        """Drop the body (stiffened servos holding ``q_joints``) until at rest."""
        m, d, idx, cfg = self.model, self.data, self.index, self.config
        mujoco.mj_resetData(m, d)
        d.qpos[:] = qpos
        d.ctrl[idx.actuators] = q_joints
        mujoco.mj_forward(m, d)
        dt = float(m.opt.timestep)
        still = 0.0
        for _ in range(round(cfg.settle_max_s / dt)):
            mujoco.mj_step(m, d)
            speed = float(np.max(np.abs(d.qvel[idx.qvel_root])))
            still = still + dt if speed < cfg.settle_speed else 0.0
            if d.time >= cfg.settle_min_s and still >= cfg.settle_hold_s:
                return d.qpos.copy(), True, float(d.time)
        return d.qpos.copy(), False, float(d.time)

    def _lift_if_penetrating(self, qpos: np.ndarray) -> tuple[np.ndarray, bool]:
        """Lift a posture that sinks into the ground beyond the checker's tolerance (soft contacts
        at rest sink a little under heavy parts); returns (qpos, valid)."""
        q = qpos.copy()
        lifted = 0.0
        while True:
            report = self.checker.check_qpos(q)
            if report.valid or not report.ground_penetration or report.self_collision or lifted >= self.config.max_lift_m:
                return q, report.valid
            q[self.index.qpos_root[2]] += self.config.lift_step_m
            lifted += self.config.lift_step_m


def estimate_posture(robot: Robot, joints_rad: Mapping[str, float], up_root: Sequence[float], *,
                     scene: str | os.PathLike[str] | None = "flat", yaw_rad: float = 0.0,
                     truth: Posture | None = None, estimator: PostureEstimator | None = None) -> PostureEstimate:
    """Estimate where the body lies (see the module docstring and :meth:`PostureEstimator.estimate`).

    Args:
        estimator: a prebuilt estimator for this robot and scene (reuse when estimating often).
    """
    if estimator is None or estimator.robot is not robot or estimator.scene != scene:
        estimator = PostureEstimator(robot, scene)
    return estimator.estimate(joints_rad, up_root, yaw_rad=yaw_rad, truth=truth)
