"""Posture space geometry for the planners: states, distance, stepping and interpolation.

OMPL's StateSpace split: geometry only, nothing about obstacles. A planner state is a flat
vector ``x = [p (3), q (4), V (n)]``: root position [m], root orientation as a unit quaternion
(w, x, y, z) and joint angles [rad] in ``robot.joint_names`` order (paper 000 section 4.1,
P = {p, q, V}).

The planner distance is paper 000 eq. (1) WITHOUT the yaw and position alignment of section 4.1
(that alignment is for comparing postures in a database; a path must really reach its goal),
plus a root position term: ``w_p |p1 - p2| + w_q ||log(q1^-1 q2)|| + dis V``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_rise.constants import PLANNER_ROOT_POSITION_WEIGHT_PER_M
from robot_rise.model import Robot
from robot_rise.posture import Posture, quat_multiply
from robot_rise.validity import ValidityChecker

__all__ = ["PostureSpace", "quat_angle", "slerp", "quat_from_rotvec"]

_P = slice(0, 3)
_Q = slice(3, 7)


def quat_angle(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """||log(q1^-1 q2)|| of paper 000 eq. (2): half the rotation angle [rad], shapes (..., 4) broadcast."""
    d = np.abs(np.sum(np.asarray(q1) * np.asarray(q2), axis=-1))
    return np.arccos(np.minimum(d, 1.0))


def slerp(q1: np.ndarray, q2: np.ndarray, s: np.ndarray | float) -> np.ndarray:
    """Spherical interpolation on the short arc.

    Args:
        q1, q2: unit quaternions (w, x, y, z), shape (4,).
        s: fractions in [0, 1], scalar or shape (m,).

    Returns:
        quaternions, shape (4,) or (m, 4).
    """
    q1 = np.asarray(q1, dtype=float)
    q2 = np.asarray(q2, dtype=float)
    dot = float(q1 @ q2)
    if dot < 0.0:
        q2, dot = -q2, -dot
    s_arr = np.asarray(s, dtype=float)
    if dot > 0.9995:  # nearly equal: normalised lerp is exact to 1e-7
        out = q1 + s_arr[..., None] * (q2 - q1)
    else:
        theta = np.arccos(dot)
        sin = np.sin(theta)
        out = (np.sin((1.0 - s_arr) * theta) / sin)[..., None] * q1 + (np.sin(s_arr * theta) / sin)[..., None] * q2
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def quat_from_rotvec(v: np.ndarray) -> np.ndarray:
    """Unit quaternion of a rotation vector (axis * full angle [rad]), shape (..., 3) -> (..., 4)."""
    v = np.asarray(v, dtype=float)
    ang = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        axis = np.where(ang > 1e-12, v / np.maximum(ang, 1e-12), 0.0)
    return np.concatenate([np.cos(ang / 2), np.sin(ang / 2) * axis], axis=-1)


@dataclass(frozen=True)
class PostureSpace:
    """Geometry of the posture space of one robot.

    Attributes:
        joint_names: joint order of V, shape (n,).
        lower, upper: joint limits [rad], shape (n,).
        joint_weights: w^i of paper 000 eq. (3), shape (n,).
        orientation_weight: w_q of eq. (1) [1/rad].
        position_weight: w_p [1/m] (ours, see constants).
    """

    robot_name: str
    joint_names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    joint_weights: np.ndarray
    orientation_weight: float
    position_weight: float = PLANNER_ROOT_POSITION_WEIGHT_PER_M

    @classmethod
    def for_robot(cls, robot: Robot) -> PostureSpace:
        return cls(
            robot.name,
            robot.joint_names,
            np.asarray(robot.joint_lower, dtype=float),
            np.asarray(robot.joint_upper, dtype=float),
            np.asarray(robot.metric_weights, dtype=float),
            float(robot.root_orientation_weight),
        )

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    @property
    def dim(self) -> int:
        """Length of a state vector: 7 + n."""
        return 7 + self.n_joints

    # --- conversions ---------------------------------------------------------------------------

    def state(self, p: Posture) -> np.ndarray:
        """Posture -> state vector, shape (7 + n,)."""
        return np.concatenate([p.root_pos, p.root_quat_wxyz, p.joint_vector(self.joint_names)])

    def posture(self, x: np.ndarray) -> Posture:
        """State vector -> Posture."""
        return Posture(self.robot_name, x[_P], x[_Q], dict(zip(self.joint_names, (float(v) for v in x[7:]))))

    def qpos(self, x: np.ndarray, checker: ValidityChecker) -> np.ndarray:
        """States -> qpos rows of the checker's model, shape (..., 7 + n) -> (..., nq)."""
        x = np.asarray(x, dtype=float)
        q = np.broadcast_to(checker.model.qpos0, x.shape[:-1] + (checker.model.nq,)).copy()
        q[..., checker.index.qpos_root] = x[..., :7]
        q[..., checker.index.qpos_joints] = x[..., 7:]
        return q

    # --- metric --------------------------------------------------------------------------------

    def distance(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Planner distance, shapes (..., 7 + n) broadcast -> leading shape (dimensionless)."""
        a = np.asarray(a)
        b = np.asarray(b)
        dp = np.linalg.norm(a[..., _P] - b[..., _P], axis=-1)
        dq = quat_angle(a[..., _Q], b[..., _Q])
        dv = a[..., 7:] - b[..., 7:]
        return self.position_weight * dp + self.orientation_weight * dq + np.sqrt(np.sum(self.joint_weights * dv * dv, axis=-1))

    def part_distances(self, a: np.ndarray, b: np.ndarray) -> tuple[float, float, float]:
        """(|dp| [m], dis Q [rad, half-angle], dis V [rad, weighted]) between two states."""
        dv = a[7:] - b[7:]
        return (
            float(np.linalg.norm(a[_P] - b[_P])),
            float(quat_angle(a[_Q], b[_Q])),
            float(np.sqrt(np.sum(self.joint_weights * dv * dv))),
        )

    # --- motion --------------------------------------------------------------------------------

    def interpolate(self, a: np.ndarray, b: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Straight motion a -> b in posture space (lerp p and V, slerp q), shape (m, 7 + n) for s of shape (m,)."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        out = a[None, :] + s[:, None] * (b - a)[None, :]
        out[:, _Q] = slerp(a[_Q], b[_Q], s)
        return out

    def step_toward(self, x_near: np.ndarray, x: np.ndarray, eps_p_m: float, eps_q_rad: float, eps_v_rad: float) -> np.ndarray:
        """Paper 000 eq. (4)-(5): step each part of x_near toward x by its own fixed step.

        A part closer than its step lands exactly on x's value and stays there (the
        unsynchronised-termination rule of section 4.2.1: a part that reaches its goal is fixed
        while the others are still planned). Joint limits are imposed (SIM, section 4.2.2).
        """
        out = np.array(x, dtype=float)
        dp, dq, dv = self.part_distances(x_near, x)
        if dp > eps_p_m:
            out[_P] = x_near[_P] + (eps_p_m / dp) * (x[_P] - x_near[_P])
        if dq > eps_q_rad:
            out[_Q] = slerp(x_near[_Q], x[_Q], eps_q_rad / dq)
        if dv > eps_v_rad:
            out[7:] = x_near[7:] + (eps_v_rad / dv) * (x[7:] - x_near[7:])
        out[7:] = np.clip(out[7:], self.lower, self.upper)
        return out

    def rotate(self, quat: np.ndarray, rotvec_body: np.ndarray) -> np.ndarray:
        """quat * exp(rotvec / 2): rotate by a body-frame rotation vector [rad], shape (4,)."""
        out = quat_multiply(quat, quat_from_rotvec(rotvec_body))
        return out / np.linalg.norm(out)
