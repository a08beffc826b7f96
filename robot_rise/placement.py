"""Placing a posture where the robot lies: turned to its facing, at its position, on its floor.

Connecting postures come from library motions recorded elsewhere; before planning, they are
turned about the vertical to the lying robot's facing direction (the yaw that minimises paper
000 eq. 2, as the metric's alignment does), moved to its x, y and rested on the surface it lies
on. When that placement collides with an obstacle, nearby placements are tried.
"""

from __future__ import annotations

import math

import numpy as np

from robot_rise.posture import Posture, quat_multiply
from robot_rise.validity import ValidityChecker

__all__ = ["best_yaw", "align_to_start", "place_near", "PLACEMENT_STEP_M", "PLACEMENT_MAX_M", "PLACEMENT_LIFTS_M"]

PLACEMENT_STEP_M = 0.05  # rings of candidate placements around the start [m]
PLACEMENT_MAX_M = 0.25
PLACEMENT_LIFTS_M = (0.0, 0.02, 0.04, 0.06, 0.08)  # candidate heights above the start's floor [m]


def best_yaw(q_ref: np.ndarray, q: np.ndarray) -> np.ndarray:
    """R_z(psi) q with psi minimising the orientation distance to q_ref (see posture.py)."""
    k = np.array([0.0, 0.0, 0.0, 1.0])
    a = float(np.dot(q_ref, q))
    b = float(np.dot(q_ref, quat_multiply(k, q)))
    half = math.atan2(b, a)
    rz = np.array([math.cos(half), 0.0, 0.0, math.sin(half)])
    out = quat_multiply(rz, q)
    return out / np.linalg.norm(out)


def align_to_start(goal: Posture, start: Posture, checker: ValidityChecker, *, xy: np.ndarray | None = None) -> Posture:
    """Goal turned to the start's facing direction, at the start's (or given) x, y, resting on z = 0."""
    quat = best_yaw(start.root_quat_wxyz, goal.root_quat_wxyz)
    pos = np.array([*(start.root_pos[:2] if xy is None else xy), 0.0])
    g = goal.with_root(pos, quat)
    low = checker.lowest_point_z(checker.qpos_of(g))
    return g.with_root(pos - np.array([0.0, 0.0, low]))


def _on_floor(goal: Posture, start: Posture, checker: ValidityChecker, xy: np.ndarray, floor_z: float) -> Posture:
    g = align_to_start(goal, start, checker, xy=xy)
    low = checker.lowest_point_z(checker.qpos_of(g))
    return g.with_root(g.root_pos + np.array([0.0, 0.0, floor_z - low]))


def _rings() -> list[np.ndarray]:
    out = [np.zeros(2)]
    r = PLACEMENT_STEP_M
    while r <= PLACEMENT_MAX_M + 1e-9:
        for a in np.linspace(0, 2 * np.pi, 8, endpoint=False):
            out.append(r * np.array([np.cos(a), np.sin(a)]))
        r += PLACEMENT_STEP_M
    return out


def place_near(goal: Posture, start: Posture, checker: ValidityChecker) -> Posture:
    """``goal`` placed where ``start`` lies: its facing, its x, y, its lowest point at the start's.

    Resting at the height the robot lies at handles the floor, a bed or a slope under the start.
    If that collides, placements on rings around the start (PLACEMENT_STEP_M up to
    PLACEMENT_MAX_M) and slightly higher (PLACEMENT_LIFTS_M, for something higher under part of
    the body) are tried, nearest first; if none is valid the first is returned and the planner
    reports why it is invalid.
    """
    floor_z = checker.lowest_point_z(checker.qpos_of(start))
    first = _on_floor(goal, start, checker, start.root_pos[:2], floor_z)
    for offset in _rings():
        base = first if not offset.any() else _on_floor(goal, start, checker, start.root_pos[:2] + offset, floor_z)
        for dz in PLACEMENT_LIFTS_M:
            candidate = base.with_root(base.root_pos + np.array([0.0, 0.0, dz]))
            if checker.is_valid(candidate):
                return candidate
    return first
