"""Postures: root position, root orientation (unit quaternion, w x y z) and joint angles by name.

File format (JSON), exactly::

    {"format": "robot-rise/posture@1", "robot": "op3", "root_pos": [x, y, z],
     "root_quat": [w, x, y, z], "joints": {"<joint>": radians, ...}}

Joint limits: a posture read for a robot may lie up to ``LIMIT_CLAMP_TOLERANCE_RAD`` (four servo
ticks) past a limit, as a servo resting on its stop reads; it is clamped into the limits with one
warning line (:func:`admit_posture`). Further out is an error naming the joints.

Also the posture distance of paper 000 section 4.1, eq. (1)-(3), vectorised.
"""

from __future__ import annotations

import json
import logging
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from robot_rise.errors import FormatError, PostureError
from robot_rise.fileio import read_json, write_text_atomic
from robot_rise.model import ModelIndex, Robot

__all__ = [
    "stand_posture",
    "Posture",
    "POSTURE_FORMAT",
    "posture_from_dict",
    "posture_to_dict",
    "read_posture",
    "write_posture",
    "validate_posture",
    "clamp_to_limits",
    "admit_posture",
    "posture_from_qpos",
    "PostureDistance",
    "yaw_aligned_orientation_distance",
    "quat_multiply",
    "quat_conjugate",
    "yaw_rad",
    "LIMIT_CLAMP_TOLERANCE_RAD",
]

log = logging.getLogger(__name__)

POSTURE_FORMAT = "robot-rise/posture@1"
QUAT_NORM_TOLERANCE = 1e-3  # |q| must be 1 within this to count as a unit quaternion
# |q| off 1 by more than this is normalised: q / |q| is not idempotent in floating point (its norm is
# 1 only to ~2e-16), so a quaternion normalised once is kept as it is (a file read back seals the same)
QUAT_RENORM_ABOVE = 1e-12
# Joint angles may lie this far past a limit and are clamped into it [rad]: four ticks of a
# 4096-tick-per-turn servo (Dynamixel XM430, 4 * 2 pi / 4096 = 6.14 mrad). A body resting on a
# limb presses the joint onto its stop, where a real servo reads it too: another team's OP3 model
# settled a shoulder 3.3 mrad past its limit (issue 40); a servo reads up to one tick past, the
# angle's rounding may add another. The one tolerance of authoring, library build, rise, check,
# execute and the guard (each admits a start through ``admit_posture`` / ``clamp_to_limits``).
LIMIT_CLAMP_TOLERANCE_RAD = 4 * 2 * math.pi / 4096
YAW_MIN_HORIZONTAL = 1e-3  # yaw_rad: an x axis with less horizontal length than this points up or down [unit]


@dataclass(frozen=True)
class Posture:
    """A whole-body posture.

    Attributes:
        robot: robot name the posture belongs to.
        root_pos: root position in the world [m], shape (3,).
        root_quat_wxyz: root orientation, unit quaternion (w, x, y, z), shape (4,).
        joints: joint angle [rad] by joint name.
    """

    robot: str
    root_pos: np.ndarray
    root_quat_wxyz: np.ndarray
    joints: Mapping[str, float]

    def __post_init__(self) -> None:
        pos = np.asarray(self.root_pos, dtype=float)
        quat = np.asarray(self.root_quat_wxyz, dtype=float)
        if pos.shape != (3,):
            raise PostureError(f"root_pos must have 3 numbers, got shape {pos.shape}")
        if quat.shape != (4,):
            raise PostureError(f"root_quat must have 4 numbers (w, x, y, z), got shape {quat.shape}")
        if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(quat))):
            raise PostureError("root_pos/root_quat contain NaN or infinity")
        norm = float(np.linalg.norm(quat))
        if abs(norm - 1.0) > QUAT_NORM_TOLERANCE:
            raise PostureError(f"root_quat is not a unit quaternion (norm {norm:.6f})")
        bad = [k for k, v in self.joints.items() if not math.isfinite(float(v))]
        if bad:
            raise PostureError(f"joint angles are NaN or infinite: {', '.join(bad)}")
        pos.setflags(write=False)
        if abs(norm - 1.0) > QUAT_RENORM_ABOVE:  # a unit quaternion stays bit for bit: a posture read back is the one written
            quat = quat / norm
        quat.setflags(write=False)
        object.__setattr__(self, "root_pos", pos)
        object.__setattr__(self, "root_quat_wxyz", quat)
        object.__setattr__(self, "joints", {str(k): float(v) for k, v in self.joints.items()})

    def joint_vector(self, joint_names: tuple[str, ...]) -> np.ndarray:
        """Joint angles in the given order [rad], shape (n,)."""
        try:
            return np.array([self.joints[n] for n in joint_names])
        except KeyError as e:
            raise PostureError(f"posture has no angle for joint {e.args[0]!r}") from None

    def qpos(self, robot: Robot, index: ModelIndex, qpos0: np.ndarray) -> np.ndarray:
        """This posture as a qpos of a composed model (other entries from ``qpos0``)."""
        q = np.array(qpos0, dtype=float)
        q[index.qpos_root[:3]] = self.root_pos
        q[index.qpos_root[3:]] = self.root_quat_wxyz
        q[index.qpos_joints] = self.joint_vector(robot.joint_names)
        return q

    def with_joints(self, joints: Mapping[str, float]) -> Posture:
        """Copy with some joint angles replaced."""
        return Posture(self.robot, self.root_pos, self.root_quat_wxyz, {**self.joints, **joints})

    def with_root(self, root_pos: np.ndarray | None = None, root_quat_wxyz: np.ndarray | None = None) -> Posture:
        """Copy with the root pose replaced."""
        return Posture(
            self.robot,
            self.root_pos if root_pos is None else root_pos,
            self.root_quat_wxyz if root_quat_wxyz is None else root_quat_wxyz,
            self.joints,
        )


def posture_from_qpos(robot: Robot, index: ModelIndex, qpos: np.ndarray) -> Posture:
    """Read a posture out of a composed model's qpos."""
    return Posture(
        robot=robot.name,
        root_pos=np.array(qpos[index.qpos_root[:3]]),
        root_quat_wxyz=np.array(qpos[index.qpos_root[3:]]),
        joints=dict(zip(robot.joint_names, (float(x) for x in qpos[index.qpos_joints]))),
    )


def stand_posture(robot: Robot) -> Posture:
    """The robot's ``stand`` keyframe as a :class:`Posture` (root pose as the keyframe has it)."""
    q = robot.stand_qpos
    return Posture(robot.name, np.asarray(q[:3]), np.asarray(q[3:7]), dict(zip(robot.joint_names, q[7:])))


def posture_to_dict(p: Posture) -> dict[str, Any]:
    """The posture@1 JSON object."""
    return {
        "format": POSTURE_FORMAT,
        "robot": p.robot,
        "root_pos": [float(x) for x in p.root_pos],
        "root_quat": [float(x) for x in p.root_quat_wxyz],
        "joints": {k: float(v) for k, v in p.joints.items()},
    }


def _number_list(obj: dict[str, Any], key: str, n: int, where: str) -> list[float]:
    v = obj.get(key)
    if not isinstance(v, list) or len(v) != n or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v):
        raise PostureError(f"{where}: {key!r} must be a list of {n} numbers, got {v!r}")
    return [float(x) for x in v]


def posture_from_dict(
    obj: Any,
    robot: Robot | None = None,
    *,
    where: str = "posture",
    limit_tolerance_rad: float = LIMIT_CLAMP_TOLERANCE_RAD,
) -> Posture:
    """Parse a posture@1 object; with ``robot``, also check joints and limits against it.

    With ``robot``, joint angles at most ``limit_tolerance_rad`` past a limit are clamped into it
    (one warning line, :func:`admit_posture`).

    Raises:
        PostureError: naming the problem (format, field, joint, quaternion, limit).
    """
    if not isinstance(obj, dict):
        raise PostureError(f"{where}: expected a JSON object")
    if obj.get("format") != POSTURE_FORMAT:
        raise PostureError(f"{where}: format is {obj.get('format')!r}, expected {POSTURE_FORMAT!r}")
    unknown_keys = set(obj) - {"format", "robot", "root_pos", "root_quat", "joints"}
    if unknown_keys:
        raise PostureError(f"{where}: unknown fields {', '.join(sorted(unknown_keys))}")
    name = obj.get("robot")
    if not isinstance(name, str) or not name:
        raise PostureError(f"{where}: 'robot' must be a non-empty string")
    pos = _number_list(obj, "root_pos", 3, where)
    quat = _number_list(obj, "root_quat", 4, where)
    joints = obj.get("joints")
    if not isinstance(joints, dict) or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in joints.values()):
        raise PostureError(f"{where}: 'joints' must map joint names to numbers (radians)")
    try:
        p = Posture(name, np.array(pos), np.array(quat), joints)
    except PostureError as e:
        raise PostureError(f"{where}: {e}") from None
    if robot is not None:
        p = admit_posture(p, robot, where=where, limit_tolerance_rad=limit_tolerance_rad)
    return p


def validate_posture(p: Posture, robot: Robot, *, where: str = "posture", limit_tolerance_rad: float = LIMIT_CLAMP_TOLERANCE_RAD) -> None:
    """Check a posture against a robot: name, joint set, limits (with tolerance).

    Raises:
        PostureError: naming the robot, the unknown/missing joints or the joints out of limits.
    """
    if p.robot != robot.name:
        raise PostureError(f"{where}: posture is for robot {p.robot!r}, not {robot.name!r}")
    unknown = sorted(set(p.joints) - set(robot.joint_names))
    missing = [j for j in robot.joint_names if j not in p.joints]
    if unknown:
        raise PostureError(f"{where}: unknown joints {', '.join(unknown)}; {robot.name} has {', '.join(robot.joint_names)}")
    if missing:
        raise PostureError(f"{where}: missing joints {', '.join(missing)}")
    q = p.joint_vector(robot.joint_names)
    out = np.flatnonzero((q < robot.joint_lower - limit_tolerance_rad) | (q > robot.joint_upper + limit_tolerance_rad))
    if out.size:
        details = ", ".join(
            f"{robot.joint_names[i]}={q[i]:.4f} not in [{robot.joint_lower[i]:.4f}, {robot.joint_upper[i]:.4f}]" for i in out
        )
        raise PostureError(
            f"{where}: joint angles out of limits: {details}",
            hint=f"up to {limit_tolerance_rad * 1e3:.2f} mrad past a limit is accepted and clamped",
        )


def clamp_to_limits(
    p: Posture, robot: Robot, *, where: str = "posture", limit_tolerance_rad: float = LIMIT_CLAMP_TOLERANCE_RAD
) -> tuple[Posture, tuple[str, ...]]:
    """The posture with joint angles slightly past a limit clamped into it (pure).

    Args:
        p: the posture (of ``robot``).
        robot: its robot (names, joints, limits).
        where: what the posture is, for the error message.
        limit_tolerance_rad: how far past a limit an angle may lie and still be clamped [rad].

    Returns:
        (the clamped posture, the names of the joints clamped, in robot order); ``p`` itself and
        ``()`` when every angle is within its limits.

    Raises:
        PostureError: as :func:`validate_posture`: another robot, unknown or missing joints, or an
            angle further than ``limit_tolerance_rad`` past its limit.
    """
    validate_posture(p, robot, where=where, limit_tolerance_rad=limit_tolerance_rad)
    q = p.joint_vector(robot.joint_names)
    inside = np.clip(q, robot.joint_lower, robot.joint_upper)
    moved = np.flatnonzero(inside != q)
    if not moved.size:
        return p, ()
    names = tuple(robot.joint_names[i] for i in moved)
    return p.with_joints({robot.joint_names[i]: float(inside[i]) for i in moved}), names


def admit_posture(
    p: Posture, robot: Robot, *, where: str = "posture", limit_tolerance_rad: float = LIMIT_CLAMP_TOLERANCE_RAD
) -> Posture:
    """:func:`clamp_to_limits`, with one warning line naming the joints clamped and by how much.

    What the product does with every posture it is given (a posture file, a trajectory's start,
    the start of ``rise``).

    Raises:
        PostureError: as :func:`validate_posture`.
    """
    inside, clamped = clamp_to_limits(p, robot, where=where, limit_tolerance_rad=limit_tolerance_rad)
    if clamped:
        log.warning(
            "%s: clamped into the joint limits: %s",
            where,
            ", ".join(f"{j} by {abs(p.joints[j] - inside.joints[j]) * 1e3:.2f} mrad" for j in clamped),
        )
    return inside


def read_posture(path: str | os.PathLike[str], robot: Robot | None = None, *, limit_tolerance_rad: float = LIMIT_CLAMP_TOLERANCE_RAD) -> Posture:
    """Read and validate a posture file; with ``robot``, angles slightly past a limit are clamped
    (:func:`posture_from_dict`).

    Raises:
        PostureError: the file is not valid JSON or not a valid posture (the message names why).
    """
    path = Path(path)
    try:
        obj = read_json(path, "posture file")
    except FormatError as e:
        raise PostureError(str(e), hint=e.hint) from None
    return posture_from_dict(obj, robot, where=str(path), limit_tolerance_rad=limit_tolerance_rad)


def write_posture(path: str | os.PathLike[str], p: Posture) -> None:
    """Write a posture file atomically (write to a temporary file, then rename)."""
    write_text_atomic(path, json.dumps(posture_to_dict(p), indent=1) + "\n")


# --- quaternions (w, x, y, z), vectorised over leading axes ---------------------------------------


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """Conjugate (inverse for unit quaternions), shape (..., 4)."""
    return np.asarray(q) * np.array([1.0, -1.0, -1.0, -1.0])


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a * b, shapes (..., 4) broadcast."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def yaw_rad(quat_wxyz: np.ndarray) -> float:
    """Heading of the body's x axis projected on the ground [rad] (0 if it points straight up or down).

    Args:
        quat_wxyz: orientation, unit quaternion (w, x, y, z), shape (4,).
    """
    w, x, y, z = (float(v) for v in quat_wxyz)
    x_x = (w * w - y * y) + (x * x - z * z)  # world x of the body's x axis (rotation matrix entry (0, 0)), summed as mju_quat2Mat does
    x_y = 2 * (x * y + w * z)  # its world y (entry (1, 0))
    return math.atan2(x_y, x_x) if math.hypot(x_x, x_y) > YAW_MIN_HORIZONTAL else 0.0


_QUAT_Z = np.array([0.0, 0.0, 0.0, 1.0])  # rotation by pi about world z


def yaw_aligned_orientation_distance(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """dis Q of paper 000 eq. (2), ||log(q1^-1 q2)||, after the best yaw alignment of q2 to q1.

    The paper aligns the facing direction before comparing (section 4.1). We take the exact
    minimum over a world-z rotation R_z(psi) applied to q2: the scalar part of
    q1^-1 R_z(psi) q2 is a cos(psi/2) + b sin(psi/2) with a = <q1, q2> and b = <q1, k q2>, so the
    best alignment has |w| = sqrt(a^2 + b^2). ||log q|| of a unit quaternion is half its rotation
    angle, acos(|w|) (the sign of w is the double cover).

    Args:
        q1, q2: unit quaternions (w, x, y, z), shapes (..., 4) broadcast.

    Returns:
        distance [rad, half-angle convention of eq. (2)], broadcast shape of the leading axes.
    """
    q1 = np.asarray(q1, dtype=float)
    q2 = np.asarray(q2, dtype=float)
    a = np.sum(q1 * q2, axis=-1)
    b = np.sum(q1 * quat_multiply(_QUAT_Z, q2), axis=-1)
    w = np.minimum(np.sqrt(a * a + b * b), 1.0)
    return np.arccos(w)


@dataclass(frozen=True)
class PostureDistance:
    """Posture distance of paper 000 eq. (1): w_q * dis Q + dis V, root aligned in position and yaw.

    Attributes:
        root_weight: w_q of eq. (1).
        joint_weights: w^i of eq. (3), shape (n,).
    """

    root_weight: float
    joint_weights: np.ndarray

    @classmethod
    def for_robot(cls, robot: Robot) -> PostureDistance:
        return cls(robot.root_orientation_weight, np.asarray(robot.metric_weights, dtype=float))

    def __call__(self, quat1: np.ndarray, joints1: np.ndarray, quat2: np.ndarray, joints2: np.ndarray) -> np.ndarray:
        """Distance between posture batches (broadcast over leading axes).

        Args:
            quat1, quat2: root quaternions (w, x, y, z), shape (..., 4).
            joints1, joints2: joint angles [rad], shape (..., n).

        Returns:
            distances, shape of the broadcast leading axes.
        """
        dq = yaw_aligned_orientation_distance(quat1, quat2)
        diff = np.asarray(joints1) - np.asarray(joints2)
        dv = np.sqrt(np.sum(self.joint_weights * diff * diff, axis=-1))
        return self.root_weight * dq + dv

    def between(self, a: Posture, b: Posture, joint_names: tuple[str, ...]) -> float:
        """Distance between two Posture objects."""
        return float(self(a.root_quat_wxyz, a.joint_vector(joint_names), b.root_quat_wxyz, b.joint_vector(joint_names)))
