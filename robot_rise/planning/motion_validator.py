"""Edge checking: is the straight posture-space motion between two postures legal?

OMPL's MotionValidator split: the ValidityChecker answers for postures, this module for motions
between them (paper 000 Fig. 2 FAILURE(x_near, x_new), section 4.2.2).

Resolution, justified: the motion a -> b (lerp root position and joints, slerp root orientation)
is checked at N + 1 evenly spaced postures, N chosen so that no point of the robot travels more
than ``resolution_m`` between two consecutive checked postures. The travel bound is the
conservative one of Schwarzer, Saha & Latombe (IEEE T-RO 2005, "exact collision checking"):

    travel <= |dp| + r_root * angle(qa, qb) + sum_i r_i |dV_i|

where r_root bounds the distance of any robot geom point from the root origin and r_i the
distance of any geom point in joint i's subtree from joint i's anchor (sum of the body offsets
along the kinematic chain plus the geom's radius about its origin, a mesh's from its convex hull:
configuration independent by the triangle inequality). Only geoms the model lets collide count
(``robot_rise.geometry``): a visual geom cannot hit anything. A geom can cross an obstacle between two checks only by travelling more
than its own thickness plus the obstacle's, so a resolution below the thinnest robot geom plus
the thinnest obstacle never skips a thin obstacle (see EDGE_RESOLUTION_M in constants).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from robot_rise.constants import EDGE_RESOLUTION_M
from robot_rise.geometry import collision_mask, colliding_geoms, geom_radius_m, mesh_hulls
from robot_rise.planning.space import PostureSpace, quat_angle
from robot_rise.validity import ValidityChecker, ValidityReport

__all__ = ["MotionValidator", "SegmentReport", "lever_arms"]


@dataclass(frozen=True)
class SegmentReport:
    """Where a motion a -> b first becomes illegal.

    Attributes:
        valid: every checked posture is legal.
        first_invalid_s: fraction along a -> b of the first illegal posture, None if valid.
        last_valid_s: fraction of the last legal posture before it (1.0 if valid).
        report: validity report of the first illegal posture (None if valid).
        n_checks: postures checked.
    """

    valid: bool
    first_invalid_s: float | None
    last_valid_s: float
    report: ValidityReport | None = None
    n_checks: int = 0


def lever_arms(checker: ValidityChecker) -> tuple[float, np.ndarray]:
    """Travel bounds of the robot's collision geometry (see module docstring).

    Returns:
        (r_root [m], r_joint [m] shape (n,)): the largest distance of a geom point from the root
        origin, and per joint from its anchor over the joint's subtree.
    """
    m = checker.model
    parent = m.body_parentid
    root = checker.index.root_body
    colliding = colliding_geoms(collision_mask(m), checker.index.robot_geoms)
    hulls = mesh_hulls(m, colliding)
    geoms = [int(g) for g in colliding]
    radius = {g: geom_radius_m(m, g, hulls.get(g)) for g in geoms}

    def chain(body: int, top: int) -> float | None:
        """Sum of |body_pos| from ``body`` up to (excluding) ``top``; None if not a descendant."""
        total = 0.0
        b = body
        while b != top:
            if b == 0:
                return None
            total += float(np.linalg.norm(m.body_pos[b]))
            b = int(parent[b])
        return total

    def reach(top: int, anchor: np.ndarray) -> float:
        best = 0.0
        for g in geoms:
            c = chain(int(m.geom_bodyid[g]), top)
            if c is None:
                continue
            best = max(best, float(np.linalg.norm(anchor)) + c + float(np.linalg.norm(m.geom_pos[g])) + radius[g])
        return best

    r_root = reach(root, np.zeros(3))
    r_joint = np.array(
        [
            reach(int(m.jnt_bodyid[j]), m.jnt_pos[j])
            for j in (int(m.jnt_qposadr.tolist().index(a)) for a in checker.index.qpos_joints)
        ]
    )
    return r_root, r_joint


@lru_cache(maxsize=512)
def _bisection_order(n: int) -> tuple[int, ...]:
    """Indices 1..n-1 in coarse-to-fine (bisection) order: collisions are found early."""
    out: list[int] = []
    seen = {0, n}
    step = n
    while step > 1:
        half = step / 2
        k = half
        while k < n:
            i = int(round(k))
            if i not in seen:
                seen.add(i)
                out.append(i)
            k += step
        step = half
    out += [i for i in range(1, n) if i not in seen]
    return tuple(out)


@dataclass
class MotionValidator:
    """Checks straight posture-space motions against one ValidityChecker.

    Not thread-safe (the checker owns one MjData). ``n_checks`` counts postures checked.

    Attributes:
        checker: the validity checker (robot, scene, looseness).
        space: the posture space.
        resolution_m: bound on any robot point's travel between checked postures [m].
    """

    checker: ValidityChecker
    space: PostureSpace
    resolution_m: float = EDGE_RESOLUTION_M
    n_checks: int = 0
    _arms: tuple[float, np.ndarray] | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if not self.resolution_m > 0:
            raise ValueError(f"resolution_m must be > 0, got {self.resolution_m}")
        if self._arms is None:
            self._arms = lever_arms(self.checker)
        self._qpos0 = self.checker.model.qpos0.copy()
        self._iroot = self.checker.index.qpos_root
        self._ijoint = self.checker.index.qpos_joints
        # a model without other coordinates (no free scene bodies) has qpos laid out as the state:
        # the two convert by copying nothing (the checker only reads them)
        nq = self.checker.model.nq
        self._same_layout = bool(
            nq == 7 + len(self._ijoint) and np.array_equal(self._iroot, np.arange(7)) and np.array_equal(self._ijoint, np.arange(7, nq))
        )

    @classmethod
    def for_checker(cls, checker: ValidityChecker, resolution_m: float = EDGE_RESOLUTION_M) -> MotionValidator:
        """The validator of the checker's robot in its own posture space."""
        return cls(checker, PostureSpace.for_robot(checker.robot), resolution_m)

    def with_checker(self, checker: ValidityChecker) -> MotionValidator:
        """Same robot geometry and resolution, another checker (e.g. another looseness)."""
        return MotionValidator(checker, self.space, self.resolution_m, _arms=self._arms)

    def with_resolution(self, resolution_m: float) -> MotionValidator:
        return MotionValidator(self.checker, self.space, resolution_m, _arms=self._arms)

    # --- geometry ------------------------------------------------------------------------------

    def travel_bound(self, a: np.ndarray, b: np.ndarray) -> float:
        """Upper bound on any robot point's travel along a -> b [m]."""
        r_root, r_joint = self._arms  # type: ignore[misc]
        return float(
            np.linalg.norm(b[:3] - a[:3]) + r_root * 2.0 * quat_angle(a[3:7], b[3:7]) + np.abs(b[7:] - a[7:]) @ r_joint
        )

    def n_steps(self, a: np.ndarray, b: np.ndarray) -> int:
        """Number of intervals the motion a -> b is checked at (>= 1)."""
        return max(1, math.ceil(self.travel_bound(a, b) / self.resolution_m))

    def _state(self, qpos: np.ndarray) -> np.ndarray:
        if self._same_layout:
            return np.asarray(qpos, dtype=float)
        return np.concatenate([qpos[self._iroot], qpos[self._ijoint]])

    def _qpos(self, x: np.ndarray) -> np.ndarray:
        if self._same_layout:
            return x
        q = self._qpos0.copy()
        q[self._iroot] = x[:7]
        q[self._ijoint] = x[7:]
        return q

    # --- checks --------------------------------------------------------------------------------

    def state_valid(self, x: np.ndarray) -> bool:
        """Is one state legal."""
        self.n_checks += 1
        return self.checker.is_valid_qpos(self._qpos(x))

    def report(self, x: np.ndarray) -> ValidityReport:
        """Full validity report of one state (reasons, clearances)."""
        return self.checker.check_qpos(self._qpos(x))

    def segment_valid(self, a: np.ndarray, b: np.ndarray, *, check_end: bool = True) -> bool:
        """Is the motion a -> b legal (a itself is assumed checked). Bisection order, early exit."""
        n = self.n_steps(a, b)
        if check_end and not self.state_valid(b):
            return False
        order = _bisection_order(n)
        if not order:
            return True
        states = self.space.interpolate(a, b, np.asarray(order, dtype=float) / n)
        for x in states:
            if not self.state_valid(x):
                return False
        return True

    def qpos_segment_valid(self, qpos_a: np.ndarray, qpos_b: np.ndarray) -> bool:
        """Is the motion between two qpos rows of the checker's model legal, both ends included.

        For planners that work on qpos rows (the energy planner); shape (nq,) each.
        """
        a, b = self._state(qpos_a), self._state(qpos_b)
        return self.state_valid(a) and self.segment_valid(a, b)

    def first_invalid(self, a: np.ndarray, b: np.ndarray) -> SegmentReport:
        """Walk a -> b in order and report the first illegal posture (a included)."""
        n = self.n_steps(a, b)
        s = np.arange(n + 1, dtype=float) / n
        states = self.space.interpolate(a, b, s)
        for k, x in enumerate(states):
            if not self.state_valid(x):
                return SegmentReport(False, float(s[k]), float(s[k - 1]) if k else -1.0, self.report(x), k + 1)
        return SegmentReport(True, None, 1.0, None, n + 1)

    def illegal_edges(self, path: np.ndarray) -> np.ndarray:
        """For a path of K states, which of its K - 1 edges are illegal, bool shape (K - 1,).

        Waypoints are checked too: an illegal waypoint makes both its edges illegal.
        """
        k = len(path)
        bad_wp = np.array([not self.state_valid(x) for x in path])
        bad = bad_wp[:-1] | bad_wp[1:]
        for i in range(k - 1):
            if not bad[i]:
                bad[i] = not self.segment_valid(path[i], path[i + 1], check_end=False)
        return bad

    def path_valid(self, path: np.ndarray) -> bool:
        """Is every waypoint and every edge of the path legal."""
        if not all(self.state_valid(x) for x in path):
            return False
        return all(self.segment_valid(path[i], path[i + 1], check_end=False) for i in range(len(path) - 1))
