"""The repulsive energy E = E_int + E_ext of paper 004 (section 4.1, eq. 1-2) and its analytic gradient.

The robot's links are capsules (``capsules``); the gradient is with respect to the posture in
MuJoCo's tangent space (root linear velocity in the world, root angular velocity in the root
frame, then joint rates; shape (nv,)), from body Jacobians (``mj_jacBody``).

Adaptation for a 0.51 m robot (ours, robot_rise/constants.py): surface distances (segment
distance minus radii) are softened below ``softening_m`` so that touching links (a lying robot
touches the ground everywhere) have a large but finite energy: h(delta) = delta + eps for
delta >= 0, eps * exp(delta / eps) below (C1, positive, increasing); each pair contributes h^-d.
The validity checker, not the energy, decides what is legal.

Thread safety: an energy object owns one MjData; make one per thread.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from robot_rise.planning.energy.capsules import (
    CapsuleSet,
    HalfSpace,
    box_corners,
    ground_halfspaces,
    non_adjacent_pairs,
    robot_capsules,
    segment_closest_points,
    world_capsules,
)
from robot_rise.geometry import collision_mask
from robot_rise.planning.energy.config import EnergyConfig
from robot_rise.validity import ValidityChecker

__all__ = ["EnergyValue", "RepulsiveEnergy"]


@dataclass(frozen=True)
class EnergyValue:
    """The energy of one posture.

    Attributes:
        total: E = E_int + E_ext (dimensionless, distances in metres).
        internal, external: the two terms of eq. (1)-(2).
        gradient: dE/dv in MuJoCo's tangent space, shape (nv,), or None if not asked.
        min_self_m: smallest capsule surface distance between non-neighbouring links [m].
        min_external_m: smallest capsule surface distance to ground/obstacles [m].
    """

    total: float
    internal: float
    external: float
    gradient: np.ndarray | None
    min_self_m: float
    min_external_m: float


def _soft(delta: np.ndarray, eps: float) -> tuple[np.ndarray, np.ndarray]:
    """h(delta) and h'(delta): delta + eps above 0, eps exp(delta/eps) below (C1, > 0)."""
    pos = delta >= 0.0
    ex = eps * np.exp(np.minimum(delta, 0.0) / eps)
    h = np.where(pos, delta + eps, ex)
    dh = np.where(pos, 1.0, ex / eps)
    return h, dh


class RepulsiveEnergy:
    """Repulsive energy of paper 004 eq. (1)-(2) for one robot in one scene, with its gradient.

    Args:
        checker: the validity checker whose model (robot + scene, no actuators) is used.
        params: energy parameters.
    """

    def __init__(self, checker: ValidityChecker, params: EnergyConfig = EnergyConfig()) -> None:
        self.params = params
        self.model = checker.model
        self.index = checker.index
        self._data = mujoco.MjData(self.model)
        m = self.model
        self.capsules: CapsuleSet = robot_capsules(m, self.index)
        self.obstacles: CapsuleSet = world_capsules(m, self.index)
        self.planes: tuple[HalfSpace, ...] = ground_halfspaces(m, self.index)
        self.pair_i, self.pair_j = non_adjacent_pairs(m, self.capsules)
        # static world capsules: endpoints fixed once
        d0 = mujoco.MjData(m)
        mujoco.mj_kinematics(m, d0)
        self._obs_a, self._obs_b = self.obstacles.world_endpoints(d0)
        # robot capsule x obstacle capsule pairs that can collide per the model (contype/conaffinity, excludes)
        self._obs_ri, self._obs_oi = np.nonzero(collision_mask(m)[np.ix_(self.capsules.geom, self.obstacles.geom)])
        self._bodies = np.unique(self.capsules.body)
        self._body_slot = {int(b): k for k, b in enumerate(self._bodies)}
        self._cap_slot = np.array([self._body_slot[int(b)] for b in self.capsules.body], dtype=int)
        # against planes, boxes count by their exact corners (capsules inside a box miss them)
        box_geoms = {int(g) for g in self.index.robot_geoms if int(m.geom_type[g]) == int(mujoco.mjtGeom.mjGEOM_BOX)}
        self._plane_caps = np.array([int(g) not in box_geoms for g in self.capsules.geom], dtype=bool)
        c_body, _, c_local = box_corners(m, self.index.robot_geoms)
        self._corner_body = c_body
        self._corner_local = c_local
        self._corner_slot = np.array([self._body_slot[int(b)] for b in c_body], dtype=int)
        self._jacp = np.zeros((3, m.nv))
        self._jacr = np.zeros((3, m.nv))

    @property
    def nv(self) -> int:
        return int(self.model.nv)

    def __call__(self, qpos: np.ndarray, *, gradient: bool = True) -> EnergyValue:
        """Energy (and gradient) of one qpos of the checker's model, shape (nq,)."""
        m, d, p = self.model, self._data, self.params
        d.qpos[:] = qpos
        mujoco.mj_kinematics(m, d)
        if gradient:
            mujoco.mj_comPos(m, d)  # cdof, needed by mj_jacBody
        caps = self.capsules
        a, b = caps.world_endpoints(d)
        eps = p.softening_m
        # points (K_points, 3) and forces dE/dx on them (gradient of E w.r.t. the point position)
        points: list[np.ndarray] = []
        forces: list[np.ndarray] = []
        slots: list[np.ndarray] = []

        # --- internal term, eq. (1): non-neighbouring capsule pairs
        i, j = self.pair_i, self.pair_j
        dist, s, t = segment_closest_points(a[i], b[i], a[j], b[j])
        delta = dist - caps.radius[i] - caps.radius[j]
        h, dh = _soft(delta, eps)
        e_int = float(np.sum(h ** (-p.falloff_d)))
        min_self = float(delta.min()) if delta.size else math.inf
        if gradient and delta.size:
            ci = a[i] + s[:, None] * (b[i] - a[i])
            cj = a[j] + t[:, None] * (b[j] - a[j])
            n = (ci - cj) / np.where(dist > 1e-12, dist, 1.0)[:, None]
            de = (-p.falloff_d * h ** (-p.falloff_d - 1) * dh)[:, None] * n  # dE/d(ci)
            points += [ci, cj]
            forces += [de, -de]
            slots += [self._cap_slot[i], self._cap_slot[j]]

        # --- external term, eq. (2): ground half-spaces and obstacle capsules
        e_ext = 0.0
        min_ext = math.inf
        q = p.external_exponent
        w = p.external_weight
        corners = d.xpos[self._corner_body] + np.einsum("cij,cj->ci", d.xmat[self._corner_body].reshape(-1, 3, 3), self._corner_local)
        pc = self._plane_caps
        for plane in self.planes:
            za = plane.signed_distance(a[pc])
            zb = plane.signed_distance(b[pc])
            low = np.where(za <= zb, 0.0, 1.0)
            # for a segment parallel to the plane every point is nearest: take the middle
            low = np.where(np.abs(za - zb) < 1e-9, 0.5, low)
            pt = np.concatenate([a[pc] + low[:, None] * (b[pc] - a[pc]), corners])
            delta_g = np.concatenate([np.minimum(za, zb) - caps.radius[pc], plane.signed_distance(corners)])
            hg, dhg = _soft(delta_g, eps)
            e_ext += w * float(np.sum(hg ** (-q)))
            min_ext = min(min_ext, float(delta_g.min()))
            if gradient:
                points.append(pt)
                forces.append((w * -q * hg ** (-q - 1) * dhg)[:, None] * plane.normal[None, :])
                slots.append(np.concatenate([self._cap_slot[pc], self._corner_slot]))
        if self._obs_ri.size:
            ri, oi = self._obs_ri, self._obs_oi
            dist_o, s_o, t_o = segment_closest_points(a[ri], b[ri], self._obs_a[oi], self._obs_b[oi])
            delta_o = dist_o - caps.radius[ri] - self.obstacles.radius[oi]
            ho, dho = _soft(delta_o, eps)
            e_ext += w * float(np.sum(ho ** (-q)))
            min_ext = min(min_ext, float(delta_o.min()))
            if gradient:
                cr = a[ri] + s_o[:, None] * (b[ri] - a[ri])
                co = self._obs_a[oi] + t_o[:, None] * (self._obs_b[oi] - self._obs_a[oi])
                n_o = (cr - co) / np.where(dist_o > 1e-12, dist_o, 1.0)[:, None]
                points.append(cr)
                forces.append((w * -q * ho ** (-q - 1) * dho)[:, None] * n_o)
                slots.append(self._cap_slot[ri])

        grad = None
        if gradient:
            grad = self._generalized_gradient(d, np.concatenate(points), np.concatenate(forces), np.concatenate(slots))
        return EnergyValue(e_int + e_ext, e_int, e_ext, grad, min_self, min_ext)

    def ground_contact_rows(self, qpos: np.ndarray, step_v: np.ndarray, zone_m: float) -> tuple[np.ndarray, np.ndarray]:
        """Active ground contacts as positional constraints (paper 004 eq. 12, ``axes=(normal,)``).

        Candidate points: the capsule end spheres and box corners within ``zone_m`` of a ground or
        obstacle plane at ``qpos`` (touching, up to the capsule approximation of the checker's
        geoms). Like the joint-limit rows of eq. (13), a row appears only for a point that the
        tangent step ``step_v`` (shape (nv,), unscaled) would lower: J_n v = C with
        C = max(0, -delta), so a touching point may slide along or lift off the plane but not sink
        (a point already below it, within the checker's tolerance, is lifted back).

        Returns:
            K (r, nv) rows in unscaled tangent coordinates and C (r,) [m].
        """
        m, d = self.model, self._data
        d.qpos[:] = qpos
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        a, b = self.capsules.world_endpoints(d)
        pc = self._plane_caps
        corners = d.xpos[self._corner_body] + np.einsum("cij,cj->ci", d.xmat[self._corner_body].reshape(-1, 3, 3), self._corner_local)
        pts = np.concatenate([a[pc], b[pc], corners])
        rad = np.concatenate([self.capsules.radius[pc], self.capsules.radius[pc], np.zeros(len(corners))])
        body = np.concatenate([self.capsules.body[pc], self.capsules.body[pc], self._corner_body]).astype(int)
        rows: list[np.ndarray] = []
        targets: list[float] = []
        jacp = self._jacp
        for plane in self.planes:
            delta = plane.signed_distance(pts) - rad
            for k in np.flatnonzero(delta < zone_m):
                mujoco.mj_jac(m, d, jacp, None, pts[k], int(body[k]))
                row = plane.normal @ jacp
                if float(row @ step_v) < 0.0:
                    rows.append(row.copy())
                    targets.append(max(0.0, -float(delta[k])))
        if not rows:
            return np.zeros((0, m.nv)), np.zeros(0)
        return np.array(rows), np.array(targets)

    def _generalized_gradient(self, d: mujoco.MjData, pts: np.ndarray, f: np.ndarray, slot: np.ndarray) -> np.ndarray:
        """Sum of J_p^T f over points p on bodies: per body, J_p^T f = jacp^T f + jacr^T (r x f)."""
        m = self.model
        nb = len(self._bodies)
        origin = d.xpos[self._bodies][slot]
        force = np.zeros((nb, 3))
        torque = np.zeros((nb, 3))
        np.add.at(force, slot, f)
        np.add.at(torque, slot, np.cross(pts - origin, f))
        grad = np.zeros(m.nv)
        jacp, jacr = self._jacp, self._jacr
        for k, body in enumerate(self._bodies):
            mujoco.mj_jacBody(m, d, jacp, jacr, int(body))
            grad += jacp.T @ force[k] + jacr.T @ torque[k]
        return grad
