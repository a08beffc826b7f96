"""The planner's chart: MuJoCo's tangent space of the posture, scaled so that one step length bounds root and joints.

A posture is a qpos row of the checker's model, shape (nq,); a motion between two is a tangent
vector, shape (nv,): root linear velocity in the world, root angular velocity in the root frame,
then joint rates (``mj_differentiatePos`` / ``mj_integratePos``: lerp of the root position and
joints, slerp of the root orientation). Root translation enters scaled (ours):
``ROOT_TRANSLATION_SCALE_M`` metres count as one radian, so one step length alpha [rad] bounds
both (``tangent_scale``).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from robot_rise.constants import ROOT_TRANSLATION_SCALE_M
from robot_rise.validity import ValidityChecker

__all__ = ["tangent_difference", "tangent_step", "tangent_scale", "resample_path"]


def tangent_difference(m: mujoco.MjModel, qpos_from: np.ndarray, qpos_to: np.ndarray) -> np.ndarray:
    """v with integrate(qpos_from, v) = qpos_to (root: world linear, body-frame angular), shape (nv,)."""
    v = np.zeros(m.nv)
    mujoco.mj_differentiatePos(m, v, 1.0, qpos_from, qpos_to)
    return v


def tangent_step(m: mujoco.MjModel, qpos: np.ndarray, v: np.ndarray) -> np.ndarray:
    """qpos moved by tangent vector v (quaternion kept unit), shape (nq,)."""
    q = np.array(qpos, dtype=float)
    mujoco.mj_integratePos(m, q, v, 1.0)
    return q


def tangent_scale(checker: ValidityChecker, root_translation_scale_m: float = ROOT_TRANSLATION_SCALE_M) -> np.ndarray:
    """Per-coordinate scale y = scale * v of the chart, shape (nv,): 1 / root_translation_scale_m on the root translation."""
    scale = np.ones(checker.model.nv)
    scale[checker.index.qvel_root[:3]] = 1.0 / root_translation_scale_m
    return scale


def resample_path(checker: ValidityChecker, path: np.ndarray, spacing_rad: float, scale: np.ndarray | None = None) -> np.ndarray:
    """A polyline of qpos rows with every segment cut into equal parts at most ``spacing_rad`` long.

    Lengths are scaled tangent-space norms (``tangent_scale``). The original rows are all kept and
    the new ones lie on the straight tangent motions between them, so the result traces the same
    motion (and is legal wherever the input's segments are).

    Args:
        path: qpos rows, shape (K, nq), K >= 1.

    Returns:
        qpos rows, shape (K', nq), K' >= K, same first and last row.
    """
    m = checker.model
    sc = scale if scale is not None else tangent_scale(checker)
    out = [np.array(path[0], dtype=float)]
    for a, b in zip(path[:-1], path[1:]):
        v = tangent_difference(m, a, b)
        n = max(1, int(math.ceil(float(np.linalg.norm(sc * v)) / spacing_rad)))
        out.extend(tangent_step(m, a, v * (k / n)) for k in range(1, n))
        out.append(np.array(b, dtype=float))
    return np.array(out)
