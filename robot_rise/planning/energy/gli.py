"""Gauss linking integral (GLI) between body linkages (paper 004 section 5.2.2, eq. 7-8).

GLI(g1, g2) = 1/(4 pi) \\int_{g1} \\int_{g2} (dg1 x dg2) . (g1 - g2) / |g1 - g2|^3   (eq. 7)

For two straight segments the double integral has a closed form: it is the signed solid angle
subtended by the quadrilateral of their four endpoints, divided by 4 pi (Klenin & Langowski,
Biopolymers 54, 2000; the analytic solution cited as [30] in paper 004). Summing it over every
segment pair of two polylines gives their GLI; for two closed, linked loops it is their integer
linking number.

The robot is split into the five linkages of paper 004 Fig. 8 (torso, left_arm, right_arm,
left_leg, right_leg; robot.toml ``[limbs]``), each a polyline through its joint anchors to the
limb's tip. ``GliMatrix`` gives the 5 x 5 matrix M_P of a posture, and ``gli_difference`` the
safe-zone measure E_gli = maxAbs(M_P1 - M_P2) of eq. 8, compared with GLI_SAFE_ZONE_THRESHOLD.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import mujoco
import numpy as np

from robot_rise.constants import GLI_SAFE_ZONE_THRESHOLD
from robot_rise.model import ModelIndex, Robot
from robot_rise.planning.energy.capsules import robot_capsules

__all__ = [
    "segment_pair_gli",
    "polyline_gli",
    "Linkage",
    "GliMatrix",
    "robot_linkages",
    "gli_difference",
    "in_safe_zone",
    "LINKAGE_ORDER",
]

log = logging.getLogger(__name__)

LINKAGE_ORDER = ("torso", "left_arm", "right_arm", "left_leg", "right_leg")  # paper 004 Fig. 8
_DEDUPE_M = 1e-3  # anchors closer than this (e.g. a 2-axis ankle) are one linkage point
_TINY = 1e-12


def _unit_cross(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    c = np.cross(a, b)
    n = np.linalg.norm(c, axis=-1)
    ok = n > _TINY
    return c / np.where(ok, n, 1.0)[..., None], ok


def segment_pair_gli(p1: np.ndarray, p2: np.ndarray, p3: np.ndarray, p4: np.ndarray) -> np.ndarray:
    """Closed-form GLI (eq. 7) between directed segments p1->p2 and p3->p4, vectorised.

    Solid angle of the quadrilateral (Klenin & Langowski 2000): with r_ij = p_j - p_i and the
    unit normals n1 = r13 x r14, n2 = r14 x r24, n3 = r24 x r23, n4 = r23 x r13,
    Omega = sign((r34 x r12) . r13) * sum asin(n_k . n_{k+1}), and GLI = Omega / (4 pi).
    Coplanar or touching segments (degenerate normals) contribute 0.

    Args:
        p1, p2: first segments [m], shape (..., 3) (broadcast).
        p3, p4: second segments [m], shape (..., 3).

    Returns:
        GLI per pair (dimensionless), shape (...,). Reversing either segment flips the sign.
    """
    p1, p2, p3, p4 = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (p1, p2, p3, p4)))
    r13, r14, r23, r24 = p3 - p1, p4 - p1, p3 - p2, p4 - p2
    r12, r34 = p2 - p1, p4 - p3
    n1, ok1 = _unit_cross(r13, r14)
    n2, ok2 = _unit_cross(r14, r24)
    n3, ok3 = _unit_cross(r24, r23)
    n4, ok4 = _unit_cross(r23, r13)

    def asin_dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.arcsin(np.clip(np.einsum("...i,...i->...", a, b), -1.0, 1.0))

    omega = asin_dot(n1, n2) + asin_dot(n2, n3) + asin_dot(n3, n4) + asin_dot(n4, n1)
    sign = np.sign(np.einsum("...i,...i->...", np.cross(r34, r12), r13))
    ok = ok1 & ok2 & ok3 & ok4
    return np.where(ok, sign * omega, 0.0) / (4.0 * np.pi)


def polyline_gli(a: np.ndarray, b: np.ndarray) -> float:
    """GLI between two directed polylines (open or closed) of points a (n+1, 3) and b (m+1, 3) [m].

    For closed loops repeat the first point at the end. Sum of the n x m segment-pair values.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    return float(np.sum(segment_pair_gli(a[:-1, None], a[1:, None], b[None, :-1], b[None, 1:])))


@dataclass(frozen=True)
class Linkage:
    """One linkage: an ordered list of points that move with the robot.

    A point is either a hinge anchor (``joint`` >= 0, world position ``data.xanchor``) or a point
    fixed in a body (``joint`` = -1, ``body`` and ``local`` [m]).

    Attributes:
        name: linkage name (paper 004 Fig. 8).
        joint: joint id per point or -1, shape (P,).
        body: body id per point (used when joint is -1), shape (P,).
        local: body-frame offset per point [m], shape (P, 3).
    """

    name: str
    joint: np.ndarray
    body: np.ndarray
    local: np.ndarray

    def points(self, data: mujoco.MjData) -> np.ndarray:
        """World positions of the points after ``mj_kinematics`` [m], shape (P, 3)."""
        out = data.xpos[self.body] + np.einsum("pij,pj->pi", data.xmat[self.body].reshape(-1, 3, 3), self.local)
        anchors = self.joint >= 0
        out[anchors] = data.xanchor[self.joint[anchors]]
        return out


def _subtree(m: mujoco.MjModel, body: int) -> set[int]:
    out = {body}
    for b in range(body + 1, m.nbody):
        if int(m.body_parentid[b]) in out:
            out.add(b)
    return out


def robot_linkages(robot: Robot, m: mujoco.MjModel, index: ModelIndex) -> tuple[Linkage, ...]:
    """The five linkages of the robot from robot.toml ``[limbs]``, in LINKAGE_ORDER.

    Each linkage runs through the anchors of its joints (coincident anchors merged) to its tip:
    the capsule endpoint in the last joint's subtree farthest from the last anchor. The torso
    linkage starts at the root body origin (the pelvis), so it spans pelvis -> neck -> head.

    Raises:
        ValueError: robot.toml lacks one of the five limbs (lists the names it needs).
    """
    missing = [n for n in LINKAGE_ORDER if n not in robot.limbs]
    if missing:
        raise ValueError(f"robot {robot.name}: [limbs] must name {', '.join(LINKAGE_ORDER)}; missing {', '.join(missing)}")
    caps = robot_capsules(m, index)
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    out = []
    for name in LINKAGE_ORDER:
        jids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in robot.limbs[name]]
        joint, body, local = [], [], []
        if name == "torso":
            joint.append(-1)
            body.append(index.root_body)
            local.append(np.zeros(3))
        for j in jids:
            joint.append(int(j))
            body.append(int(m.jnt_bodyid[j]))
            local.append(np.zeros(3))
        last = jids[-1]
        sub = _subtree(m, int(m.jnt_bodyid[last]))
        anchor = d.xanchor[last]
        best, best_dist = None, -1.0
        for g in np.unique(caps.geom):
            ks = np.flatnonzero(caps.geom == g)
            b = int(caps.body[ks[0]])
            if b not in sub:
                continue
            # the centre of a geom's end (a box gives parallel capsules: average their ends)
            for loc in (caps.a_local[ks].mean(axis=0), caps.b_local[ks].mean(axis=0)):
                w = d.xpos[b] + d.xmat[b].reshape(3, 3) @ loc
                dist = float(np.linalg.norm(w - anchor))
                if dist > best_dist:
                    best, best_dist = (b, np.array(loc)), dist
        if best is not None:
            joint.append(-1)
            body.append(best[0])
            local.append(best[1])
        lk = Linkage(name, np.array(joint, dtype=int), np.array(body, dtype=int), np.array(local, dtype=float))
        pts = lk.points(d)
        keep = [0] + [i for i in range(1, len(pts)) if np.linalg.norm(pts[i] - pts[i - 1]) > _DEDUPE_M]
        out.append(Linkage(name, lk.joint[keep], lk.body[keep], lk.local[keep]))
    return tuple(out)


class GliMatrix:
    """GLI matrix M_P of a posture (paper 004 section 5.2.2): GLI between every two linkages.

    Owns one MjData; not thread-safe.
    """

    def __init__(self, robot: Robot, m: mujoco.MjModel, index: ModelIndex) -> None:
        self.model = m
        self.index = index
        self.linkages = robot_linkages(robot, m, index)
        self._data = mujoco.MjData(m)
        sizes = [len(lk.joint) - 1 for lk in self.linkages]
        starts = np.concatenate([[0], np.cumsum(sizes)])
        si, sj, li, lj = [], [], [], []
        for a in range(len(sizes)):
            for b in range(a + 1, len(sizes)):
                ga, gb = np.meshgrid(np.arange(starts[a], starts[a + 1]), np.arange(starts[b], starts[b + 1]), indexing="ij")
                si.append(ga.ravel())
                sj.append(gb.ravel())
                li.append(np.full(ga.size, a))
                lj.append(np.full(ga.size, b))
        self._si, self._sj = np.concatenate(si), np.concatenate(sj)
        self._li, self._lj = np.concatenate(li), np.concatenate(lj)
        self._seg_start = np.concatenate([np.arange(starts[k], starts[k + 1]) + k for k in range(len(sizes))])

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(lk.name for lk in self.linkages)

    def polylines(self, qpos: np.ndarray) -> list[np.ndarray]:
        """Linkage points in the world for one qpos, list of (P_k, 3) arrays [m]."""
        d = self._data
        d.qpos[:] = qpos
        mujoco.mj_kinematics(self.model, d)
        return [lk.points(d) for lk in self.linkages]

    def __call__(self, qpos: np.ndarray) -> np.ndarray:
        """M_P for one qpos of the composed model: symmetric (5, 5), zero diagonal."""
        pts = np.concatenate(self.polylines(qpos))
        s0 = pts[self._seg_start]
        s1 = pts[self._seg_start + 1]
        g = segment_pair_gli(s0[self._si], s1[self._si], s0[self._sj], s1[self._sj])
        n = len(self.linkages)
        mat = np.zeros((n, n))
        np.add.at(mat, (self._li, self._lj), g)
        return mat + mat.T


def gli_difference(m1: np.ndarray, m2: np.ndarray) -> float:
    """E_gli of paper 004 eq. (8): the largest absolute entry of M_P1 - M_P2."""
    return float(np.max(np.abs(np.asarray(m1) - np.asarray(m2))))


def in_safe_zone(m1: np.ndarray, m2: np.ndarray, threshold: float = GLI_SAFE_ZONE_THRESHOLD) -> bool:
    """True when two postures may be linearly interpolated (eq. 8 below the threshold, 0.3)."""
    return gli_difference(m1, m2) < threshold
