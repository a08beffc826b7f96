"""Energy-driven planning between two distant postures (paper 004, Wang, Ho & Komura 2015).

Pieces, each from the paper section named beside it:

- ``RepulsiveEnergy``: E = E_int + E_ext (section 4.1, eq. 1-2) over the robot's links as
  capsules (robot_rise.planning.capsules), with its analytic gradient with respect to the posture
  in MuJoCo's tangent space (root linear velocity in the world, root angular velocity in the root
  frame, then joint rates; shape (nv,)), from body Jacobians (``mj_jacBody``).
- ``plan_energy`` / ``energy_interpolate``: energy-descent bidirectional interpolation
  (section 5.1, Algorithm 1) with the safe zone of the Gauss linking integral (section 5.2.2,
  eq. 7-8) and constrained planning by null-space projection (section 6.1, Algorithm 2,
  eq. 9-13: joint limits and positional constraints such as a hand kept on the ground).
- ``EnergyWindow``: the local-minimum detector of section 8.
- ``safe_zone_keyframes``: the output of each leg reduced to its key postures, consecutive ones in
  one safe subspace (section 5.2: eq. 8 below the threshold and a legal straight motion), instead
  of every alpha step (Algorithm 1's direct and projected steps zig-zag at the step scale).
- ``straighten_limbs``: the root and each linkage of Fig. 8 that the key postures move and bring
  back without need (section 5.1's "unnecessary expansion") put on its straight motion where
  that is legal (ours).
- ``second_stage``: the section 6.2 projection of the motion (eq. 14, 19-20 with M = I): frames
  kept close to the first-stage motion, a Laplacian smoothness term on the trajectory, the
  linear-momentum term of eq. (18) (weight 0 by default, as in the paper's eq. 20), joint limits
  and positional constraints as hard constraints, and the validity checker as the judge of every frame and segment (no new penetration);
  ``dense_output`` then writes the motion out densely for the shared timing.

Adaptations for a 0.51 m robot (marked "ours" in robot_rise/constants.py):

- Surface distances (segment distance minus radii) are softened below ``softening_m`` so that
  touching links (a lying robot touches the ground everywhere) have a large but finite energy:
  h(delta) = delta + eps for delta >= 0, eps * exp(delta / eps) below (C1, positive, increasing);
  each pair contributes h^-d. The validity checker, not the energy, decides what is legal: every
  accepted step is checked, and the final path is verified at a fixed travel resolution.
- The ground is always there, so the safe-zone rule "linear step if E_gli < 0.3 and O is empty"
  becomes "linear step if E_gli < 0.3 and the linear step is legal".
- A projected step (I - g g^T) D keeps the energy level only to first order; we add a small
  descent component -beta g so the energy of the moving end really decreases (as Algorithm 1's
  expansion toward the canonical postures of section 5.1 intends).
- Ground contacts as automatic positional constraints (Algorithm 2, eq. 12): a lying robot
  rests on the floor, and with d = 3 the internal term (exponent d) can outweigh the ground term
  (exponent 2), so its gradient pushes a resting foot or the torso through the floor and every
  attempt of Algorithm 1 is rejected. Then the attempts are repeated with the touching points
  (within GROUND_CONTACT_ZONE_M) that the step would lower held on the plane, in the active-set
  manner of the joint-limit rows of eq. (13). Section 8 of the paper assumes such "contact
  invariant" segments.
- Root translation enters the tangent space scaled: ``ROOT_TRANSLATION_SCALE_M`` metres count as
  one radian, so one step length alpha [rad] bounds both.

Thread safety: an energy object owns one MjData; make one per thread.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from robot_rise.constants import (
    ENERGY_CONSTRAINT_GAMMA,
    ENERGY_CONSTRAINT_OMEGA,
    ENERGY_DESCENT_BETA,
    ENERGY_EXTERNAL_EXPONENT,
    ENERGY_EXTERNAL_WEIGHT,
    ENERGY_FALLOFF_D,
    ENERGY_LOCAL_MINIMUM_PATIENCE,
    ENERGY_MAX_ITERATIONS,
    ENERGY_SOFTENING_M,
    ENERGY_STEP_RAD,
    ENERGY_VERIFY_RESOLUTION_M,
    ENERGY_WINDOW_FRACTION,
    FALLOFF_RETRY_SCHEDULE,
    GLI_SAFE_ZONE_THRESHOLD,
    GROUND_CONTACT_ZONE_M,
    OUTPUT_SPACING_RAD,
    ROOT_TRANSLATION_SCALE_M,
    SECOND_STAGE_FRAME_SPACING_RAD,
    SECOND_STAGE_HALVINGS,
    SECOND_STAGE_ITERATIONS,
    SECOND_STAGE_TOLERANCE_RAD,
    SECOND_STAGE_W_LAP,
    SECOND_STAGE_W_LM,
)
from robot_rise.planning.capsules import (
    CapsuleSet,
    HalfSpace,
    box_corners,
    ground_halfspaces,
    non_adjacent_pairs,
    robot_capsules,
    segment_closest_points,
    world_capsules,
)
from robot_rise.planning.gli import LINKAGE_ORDER, GliMatrix, gli_difference
from robot_rise.planning.motion_validator import lever_arms
from robot_rise.planning.problem import PlanningProblem, PlanResult, PlanStatus, PostureSequence
from robot_rise.planning.timing import integrated_squared_jerk, time_parameterize
from robot_rise.posture import Posture, posture_from_qpos
from robot_rise.validity import ValidityChecker

__all__ = [
    "EnergyParams",
    "EnergyValue",
    "RepulsiveEnergy",
    "PositionalConstraint",
    "EnergyWindow",
    "InterpolationOutcome",
    "energy_interpolate",
    "plan_energy",
    "EnergyPlanner",
    "FALLOFF_RETRY_SCHEDULE",
    "GROUND_CONTACT_ZONE_M",
    "safe_zone_keyframes",
    "straighten_limbs",
    "tangent_difference",
    "tangent_step",
    "segment_is_valid",
    "SecondStageParams",
    "second_stage",
    "resample_path",
    "trajectory_laplacian_energy",
    "dense_output",
]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SecondStageParams:
    """Parameters of the section 6.2 projection (``second_stage``; defaults in robot_rise/constants.py).

    Attributes:
        iterations: maximum iterations (paper: 30).
        frame_spacing_rad: the first-stage motion is resampled so that consecutive frames are at
            most this far apart in the scaled tangent space [rad].
        w_lap: weight of the trajectory Laplacian (second difference of the frames), eq. (19).
        w_lm: weight of the linear-momentum deviation of eq. (18) (CoM second difference).
        halvings: step halvings of a frame made illegal before it keeps its previous posture.
        tolerance_rad: stop when no frame moves more than this [rad].
    """

    iterations: int = SECOND_STAGE_ITERATIONS
    frame_spacing_rad: float = SECOND_STAGE_FRAME_SPACING_RAD
    w_lap: float = SECOND_STAGE_W_LAP
    w_lm: float = SECOND_STAGE_W_LM
    halvings: int = SECOND_STAGE_HALVINGS
    tolerance_rad: float = SECOND_STAGE_TOLERANCE_RAD

    def __post_init__(self) -> None:
        if self.frame_spacing_rad <= 0 or self.w_lap < 0 or self.w_lm < 0 or self.iterations < 0 or self.halvings < 0:
            raise ValueError("second stage: spacing must be positive; weights, iterations and halvings non-negative")


@dataclass(frozen=True)
class EnergyParams:
    """Parameters of the energy and of Algorithms 1-2 (defaults in robot_rise/constants.py).

    Attributes:
        falloff_d: fall-off exponent d of eq. (1) (paper: 2..5).
        external_exponent: exponent of eq. (2) (paper: 2).
        softening_m: softening length of the surface distance [m] (ours).
        external_weight: weight of E_ext against E_int (paper: 1).
        step_rad: step length alpha of eq. (4)-(5) in the scaled tangent space [rad].
        descent_beta: extra descent on a projected step, fraction of alpha (ours).
        gli_threshold: safe-zone threshold of eq. (8) (paper: 0.3).
        use_safe_zone: take linear steps inside the safe zone (section 5.2.2).
        patience: local-minimum iterations of section 8 (paper: 50).
        window_fraction: height of the energy window, fraction of its top energy (ours).
        gamma, omega: eq. (10)-(11) constants (paper: 0.01, -0.01).
        max_iterations: hard cap on iterations.
        verify_resolution_m: travel bound between checked postures of the output path [m].
        root_translation_scale_m: metres of root travel that count as one radian (ours).
        move_root: let the energy move the root (position and orientation); if False, the root
            follows the straight interpolation only and the energy acts on the joints.
        ground_contacts: when every plain attempt of an iteration is rejected, repeat them with
            the touched ground as positional constraints (Algorithm 2; ours: automatic contacts).
        keyframes: ``plan_energy`` returns the key postures of each leg (``safe_zone_keyframes``,
            section 5.2) instead of every alpha step.
        straighten_limbs: undo the expansion of the root and of each linkage that a leg's key
            postures do not need (``straighten_limbs``; ours, section 5.1's "unnecessary
            expansion"), before the second stage.
        dense_output: write the second stage's motion out densely (``dense_output``).
        second_stage: project each leg's motion by ``second_stage`` (section 6.2); on by default
            (None: off). On by measurement (BENCHMARKS.md, issue 7, first round): through the
            shared smoother it was smoother than the key postures alone on 58/60 lying problems
            and 15/15 crossed-limb problems (dimensionless jerk, median ratio 0.05). With the
            straightening and the dense output (second round) the planner is the smoothest of
            the three benchmarked at a common duration on all 75 problems.
    """

    falloff_d: int = ENERGY_FALLOFF_D
    external_exponent: int = ENERGY_EXTERNAL_EXPONENT
    softening_m: float = ENERGY_SOFTENING_M
    external_weight: float = ENERGY_EXTERNAL_WEIGHT
    step_rad: float = ENERGY_STEP_RAD
    descent_beta: float = ENERGY_DESCENT_BETA
    gli_threshold: float = GLI_SAFE_ZONE_THRESHOLD
    use_safe_zone: bool = True
    patience: int = ENERGY_LOCAL_MINIMUM_PATIENCE
    window_fraction: float = ENERGY_WINDOW_FRACTION
    gamma: float = ENERGY_CONSTRAINT_GAMMA
    omega: float = ENERGY_CONSTRAINT_OMEGA
    max_iterations: int = ENERGY_MAX_ITERATIONS
    verify_resolution_m: float = ENERGY_VERIFY_RESOLUTION_M
    root_translation_scale_m: float = ROOT_TRANSLATION_SCALE_M
    move_root: bool = True
    ground_contacts: bool = True
    keyframes: bool = True
    straighten_limbs: bool = True
    dense_output: bool = True
    second_stage: SecondStageParams | None = field(default_factory=SecondStageParams)

    def __post_init__(self) -> None:
        if self.falloff_d < 1:
            raise ValueError(f"falloff_d must be >= 1 (paper 004 section 4.2), got {self.falloff_d}")
        if self.softening_m <= 0 or self.step_rad <= 0 or self.verify_resolution_m <= 0:
            raise ValueError("softening_m, step_rad and verify_resolution_m must be positive")


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

    def __init__(self, checker: ValidityChecker, params: EnergyParams = EnergyParams()) -> None:
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
        if len(self.obstacles):
            k_r = np.arange(len(caps))
            ri, oi = np.meshgrid(k_r, np.arange(len(self.obstacles)), indexing="ij")
            ri, oi = ri.ravel(), oi.ravel()
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


# --- tangent-space helpers ------------------------------------------------------------------------


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


def _travel_bound(levers: tuple[float, np.ndarray], v: np.ndarray, idx_root: slice, dof_joints: np.ndarray) -> float:
    """Upper bound on the travel [m] of any robot point for the tangent motion v."""
    r_root, r_joint = levers
    return float(np.linalg.norm(v[0:3]) + r_root * np.linalg.norm(v[3:6]) + np.sum(r_joint * np.abs(v[dof_joints])))


def segment_is_valid(
    checker: ValidityChecker,
    qpos_a: np.ndarray,
    qpos_b: np.ndarray,
    *,
    resolution_m: float = ENERGY_VERIFY_RESOLUTION_M,
    levers: tuple[float, np.ndarray] | None = None,
) -> bool:
    """Is the straight tangent-space motion qpos_a -> qpos_b legal at the given travel resolution?

    The motion is lerp of root position and joints and slerp of the root orientation; it is
    checked at evenly spaced postures such that no robot point travels more than
    ``resolution_m`` between two of them (both ends included).
    """
    m = checker.model
    v = tangent_difference(m, qpos_a, qpos_b)
    lev = levers if levers is not None else lever_arms(checker)
    n = max(1, int(math.ceil(_travel_bound(lev, v, slice(0, 6), checker.index.dof_joints) / resolution_m)))
    for k in range(n + 1):
        if not checker.is_valid_qpos(tangent_step(m, qpos_a, v * (k / n))):
            return False
    return True


# --- constraints (Algorithm 2) --------------------------------------------------------------------


@dataclass(frozen=True)
class PositionalConstraint:
    """Keep a point of a body at a target (paper 004 eq. 12), e.g. a hand or knee on the ground.

    Attributes:
        body: body name.
        local_point: the point in the body frame [m], shape (3,).
        target: target world position [m], shape (3,); only ``axes`` are constrained.
        axes: world axes constrained (0 = x, 1 = y, 2 = z), e.g. (2,) keeps only the height.
    """

    body: str
    local_point: np.ndarray
    target: np.ndarray
    axes: tuple[int, ...] = (0, 1, 2)

    def __post_init__(self) -> None:
        object.__setattr__(self, "local_point", np.asarray(self.local_point, dtype=float).reshape(3))
        object.__setattr__(self, "target", np.asarray(self.target, dtype=float).reshape(3))
        if not self.axes or any(a not in (0, 1, 2) for a in self.axes):
            raise ValueError(f"axes must be a non-empty subset of (0, 1, 2), got {self.axes}")


class _Constraints:
    """Linearised constraints K dq = C (eq. 9) at one posture: joint limits (eq. 13) and positions (eq. 12)."""

    def __init__(self, checker: ValidityChecker, positional: tuple[PositionalConstraint, ...], scale: np.ndarray) -> None:
        self.model = checker.model
        self.index = checker.index
        self.lower = checker.robot.joint_lower
        self.upper = checker.robot.joint_upper
        self.positional = positional
        self.scale = scale  # tangent scaling: y = scale * v
        self._data = mujoco.MjData(self.model)
        self._bodies = []
        for c in positional:
            b = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, c.body)
            if b < 0:
                names = [self.model.body(k).name for k in range(self.model.nbody)]
                raise ValueError(f"positional constraint: no body {c.body!r}; bodies: {', '.join(names)}")
            self._bodies.append(b)

    def rows(self, qpos: np.ndarray, step_y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """K (r, nv) in scaled coordinates and C (r,) for the step about to be taken.

        Joint-limit rows appear only for joints the step would carry past a bound (eq. 13);
        positional rows always (a point kept on the ground must not drift).
        """
        K_rows: list[np.ndarray] = []
        C: list[float] = []
        qj = qpos[self.index.qpos_joints]
        dj = step_y[self.index.dof_joints] / self.scale[self.index.dof_joints]
        nxt = qj + dj
        for k in np.flatnonzero((nxt < self.lower) | (nxt > self.upper)):
            row = np.zeros(self.model.nv)
            row[self.index.dof_joints[k]] = 1.0 / self.scale[self.index.dof_joints[k]]
            bound = self.lower[k] if nxt[k] < self.lower[k] else self.upper[k]
            K_rows.append(row)
            C.append(float(np.clip(bound, self.lower[k], self.upper[k]) - qj[k]))
        if self.positional:
            d = self._data
            d.qpos[:] = qpos
            mujoco.mj_kinematics(self.model, d)
            mujoco.mj_comPos(self.model, d)
            jacp = np.zeros((3, self.model.nv))
            for c, b in zip(self.positional, self._bodies):
                x = d.xpos[b] + d.xmat[b].reshape(3, 3) @ c.local_point
                mujoco.mj_jac(self.model, d, jacp, None, x, b)
                for ax in c.axes:
                    K_rows.append(jacp[ax] / self.scale)
                    C.append(float(c.target[ax] - x[ax]))
        if not K_rows:
            return np.zeros((0, self.model.nv)), np.zeros(0)
        return np.array(K_rows), np.array(C)

    def positional_error(self, qpos: np.ndarray) -> float:
        """Largest positional-constraint violation [m] (0 without positional constraints)."""
        if not self.positional:
            return 0.0
        d = self._data
        d.qpos[:] = qpos
        mujoco.mj_kinematics(self.model, d)
        err = 0.0
        for c, b in zip(self.positional, self._bodies):
            x = d.xpos[b] + d.xmat[b].reshape(3, 3) @ c.local_point
            err = max(err, float(np.max(np.abs(x[list(c.axes)] - c.target[list(c.axes)]))))
        return err


def _project_constraints(dq: np.ndarray, K: np.ndarray, C: np.ndarray, g_hat: np.ndarray, p: EnergyParams) -> np.ndarray:
    """Eq. (10), then eq. (11) if the constrained step would raise the energy.

    Eq. (10): the minimum-norm change of the step dq such that K dq' = C, solved in the damped
    least-squares sense (soft constraints, rank-deficient K allowed; damping gamma of the paper).
    Eq. (11): if dq' . g > 0, the energy row is stacked under K, J = [K; g^T], with target
    [C; omega] (omega < 0: a small energy decrease along the normalised gradient).

    Args:
        dq: the step in scaled tangent coordinates, shape (nv,).
        K, C: constraint rows (r, nv) and targets (r,).
        g_hat: normalised energy gradient in scaled tangent coordinates, shape (nv,).
    """
    if K.shape[0] == 0:
        return dq
    damp = p.gamma * p.gamma
    lam = np.linalg.lstsq(K @ K.T + damp * np.eye(K.shape[0]), K @ dq - C, rcond=None)[0]
    dq1 = dq - K.T @ lam
    if float(dq1 @ g_hat) <= 0.0 or not np.any(g_hat):
        return dq1
    J = np.vstack([K, g_hat[None, :]])
    target = np.concatenate([C, [p.omega]])
    lam_e = np.linalg.lstsq(J @ J.T + damp * np.eye(J.shape[0]), J @ dq - target, rcond=None)[0]
    return dq - J.T @ lam_e


def _with_ground_contacts(
    energy: RepulsiveEnergy, qh: np.ndarray, dy: np.ndarray, K: np.ndarray, C: np.ndarray, g_hat: np.ndarray, scale: np.ndarray, p: EnergyParams
) -> tuple[np.ndarray, np.ndarray]:
    """K, C of the step extended by the ground contacts it would push through (active set, 3 passes).

    A contact row is added for every touching point the (projected) step would carry below the
    ground; projecting can push other points down, so the active set is recomputed from the
    projected step, keeping the rows found before.
    """
    rows: list[np.ndarray] = []
    targets: list[float] = []
    step = dy
    for _ in range(3):
        Kc, Cc = energy.ground_contact_rows(qh, step / scale, GROUND_CONTACT_ZONE_M)
        new = [(r / scale, c) for r, c in zip(Kc, Cc) if not any(np.allclose(r / scale, x) for x in rows)]
        if not new:
            break
        rows += [r for r, _ in new]
        targets += [c for _, c in new]
        KK = np.vstack([K, np.array(rows)])
        CC = np.concatenate([C, np.array(targets)])
        step = _project_constraints(dy, KK, CC, g_hat, p)
    if not rows:
        return K, C
    return np.vstack([K, np.array(rows)]), np.concatenate([C, np.array(targets)])


# --- local minimum (section 8) --------------------------------------------------------------------


@dataclass
class EnergyWindow:
    """Local-minimum detector of paper 004 section 8 (mutable state of one planning run).

    The window starts below the higher of the two initial energies; each iteration, if the lower
    energy of the two ends falls out of the window, the window slides down to contain it. When
    the ends stay in one window for ``patience`` iterations, it is a local minimum. Ours: an
    iteration in which the two ends come closer than ever before by at least a tenth of a step
    also counts as progress (linear safe-zone steps move without changing the energy much).
    """

    top: float
    fraction: float
    patience: int
    best_gap: float = math.inf
    stuck: int = 0

    def update(self, e_low: float, gap: float, min_progress: float) -> bool:
        """Feed one iteration; True when a local minimum is detected."""
        bottom = self.top * (1.0 - self.fraction)
        progressed = False
        if e_low < bottom:
            self.top = e_low
            progressed = True
        if gap < self.best_gap - min_progress:
            self.best_gap = gap
            progressed = True
        self.stuck = 0 if progressed else self.stuck + 1
        return self.stuck >= self.patience


# --- Algorithms 1 and 2 ---------------------------------------------------------------------------


@dataclass(frozen=True)
class InterpolationOutcome:
    """Result of ``energy_interpolate``.

    Attributes:
        status: EXACT_SOLUTION, FAILED (local minimum / blocked / verification), TIMEOUT, INVALID_*.
        qpos: the path as qpos rows of the checker's model, shape (K, nq) (None on failure).
        reason: why it failed; empty on success.
        stats: counters (iterations, linear/projected/constrained steps, energies, seconds).
    """

    status: PlanStatus
    qpos: np.ndarray | None
    reason: str = ""
    stats: dict[str, Any] = field(default_factory=dict)


def _tangent_scale(checker: ValidityChecker, root_translation_scale_m: float = ROOT_TRANSLATION_SCALE_M) -> np.ndarray:
    scale = np.ones(checker.model.nv)
    scale[checker.index.qvel_root[:3]] = 1.0 / root_translation_scale_m
    return scale


def _past(deadline: float | None) -> bool:
    """Has the ``time.monotonic()`` deadline passed (None: no deadline)?"""
    return deadline is not None and time.monotonic() >= deadline


def energy_interpolate(
    checker: ValidityChecker,
    qpos_start: np.ndarray,
    qpos_goal: np.ndarray,
    *,
    params: EnergyParams = EnergyParams(),
    constraints: tuple[PositionalConstraint, ...] = (),
    budget_s: float = 30.0,
    energy: RepulsiveEnergy | None = None,
    gli: GliMatrix | None = None,
) -> InterpolationOutcome:
    """Energy-based bidirectional interpolation (paper 004 Algorithm 1; Algorithm 2 with constraints).

    Each iteration moves the end of higher energy, P_h, toward the other, P_l, by one step of
    length alpha in the scaled tangent space: linearly inside the safe zone (eq. 8), else along
    D = (P_l - P_h)/|P_l - P_h| if that does not raise the energy, else along the projection
    (I - g g^T) D with a little descent (eq. 5). Joint limits and positional constraints are
    enforced by the null-space projections of eq. (10)-(11). Every accepted posture is legal for
    ``checker``; when the two ends can be joined by a legal straight motion they are, and the
    whole path M_1 + reverse(M_2) is verified at ``params.verify_resolution_m``.

    Args:
        checker: the strict validity checker (robot + scene).
        qpos_start, qpos_goal: qpos of the checker's model, shape (nq,).
        params: energy and algorithm parameters.
        constraints: positional constraints kept along the whole path (Algorithm 2).
        budget_s: wall-clock budget [s].
        energy, gli: reuse prebuilt objects (they are rebuilt from the checker otherwise).

    Returns:
        InterpolationOutcome; failures carry a status and a reason, never an exception.
    """
    t0 = time.monotonic()
    p = params
    m = checker.model
    if not checker.is_valid_qpos(qpos_start):
        return InterpolationOutcome(PlanStatus.INVALID_START, None, "start: " + "; ".join(checker.check_qpos(qpos_start).reasons()))
    if not checker.is_valid_qpos(qpos_goal):
        return InterpolationOutcome(PlanStatus.INVALID_GOAL, None, "goal: " + "; ".join(checker.check_qpos(qpos_goal).reasons()))
    energy = energy if energy is not None else RepulsiveEnergy(checker, p)
    gli = gli if gli is not None else GliMatrix(checker.robot, m, checker.index)
    scale = _tangent_scale(checker, p.root_translation_scale_m)
    cons = _Constraints(checker, constraints, scale)
    levers = lever_arms(checker)
    root = np.asarray(checker.index.qvel_root)
    alpha = p.step_rad

    ends = [np.array(qpos_start, dtype=float), np.array(qpos_goal, dtype=float)]
    paths: list[list[np.ndarray]] = [[ends[0].copy()], [ends[1].copy()]]
    evals = [energy(ends[0]), energy(ends[1])]
    glis = [gli(ends[0]), gli(ends[1])]
    window = EnergyWindow(max(evals[0].total, evals[1].total), p.window_fraction, p.patience)
    stats: dict[str, Any] = {
        "iterations": 0,
        "direct_steps": 0,
        "projected_steps": 0,
        "descent_steps": 0,
        "constrained_steps": 0,
        "contact_steps": 0,
        "rejected_steps": 0,
        "connect_attempts": 0,
        "safe_zone_refuted": 0,
        "energy_start": evals[0].total,
        "energy_goal": evals[1].total,
    }

    def finish(status: PlanStatus, reason: str, q: np.ndarray | None) -> InterpolationOutcome:
        stats["seconds"] = time.monotonic() - t0
        return InterpolationOutcome(status, q, reason, stats)

    last_connect_gap = math.inf
    for it in range(p.max_iterations):
        stats["iterations"] = it + 1
        if time.monotonic() - t0 > budget_s:
            return finish(PlanStatus.TIMEOUT, f"budget of {budget_s:.1f} s spent after {it} iterations", None)
        v_gap = tangent_difference(m, ends[0], ends[1])
        gap = float(np.linalg.norm(scale * v_gap))
        e_gli = gli_difference(glis[0], glis[1])
        safe = p.use_safe_zone and e_gli < p.gli_threshold
        # section 5.2.2: inside the safe zone, f = f1 + lerp(P1e, P2e) + f2. We ask the checker
        # whether the straight motion between the ends is legal instead of trusting eq. (8) alone
        # (short, thick robot links can stay under the threshold while crossed); tried again
        # whenever the gap shrank by a fifth, and always within one step
        # (with positional constraints only within one step: a long straight motion ignores them)
        if gap <= alpha or (safe and not constraints and gap < 0.8 * last_connect_gap):
            stats["connect_attempts"] += 1
            last_connect_gap = gap
            if segment_is_valid(checker, ends[0], ends[1], resolution_m=p.verify_resolution_m, levers=levers):
                path = np.array(paths[0] + paths[1][::-1])
                return _verified(checker, path, p, levers, finish, stats)
            if safe:
                stats["safe_zone_refuted"] += 1  # eq. (8) said safe, the checker said no
        h = 0 if evals[0].total >= evals[1].total else 1
        lo = 1 - h
        qh = ends[h]
        D = scale * tangent_difference(m, qh, ends[lo])
        D_hat = D / max(float(np.linalg.norm(D)), 1e-12)
        g = evals[h].gradient / scale
        if not p.move_root:
            g = g.copy()
            g[root] = 0.0
        g_norm = float(np.linalg.norm(g))
        g_hat = g / g_norm if g_norm > 1e-12 else np.zeros_like(g)

        accepted = False
        # Attempts, in order: the paper's step (D if it does not climb, else eq. 5), then more and
        # more descent (a rejected step collided or climbed: move away from the nearest links),
        # then pure descent (eq. 4) at halving lengths. Algorithm 1 steps linearly inside the safe
        # zone only when there is no environment (O empty); the ground is always there, so the
        # safe zone here only triggers the straight connection above.
        proj = D_hat - g_hat * float(g_hat @ D_hat)  # eq. (5): (I - g g^T) D
        plan: list[tuple[str, np.ndarray]] = []
        if float(D_hat @ g_hat) <= 0.0:
            plan.append(("direct_steps", D_hat * min(alpha, gap)))
        for beta in (p.descent_beta, 1.0, 3.0):
            plan.append(("projected_steps", alpha * (proj - beta * g_hat)))
        for frac in (1.0, 0.5, 0.25, 0.125):
            plan.append(("descent_steps", -alpha * frac * g_hat))
        # then the same attempts again with the touched ground as positional constraints (Algorithm 2)
        plan_all = [(kind, dy, False) for kind, dy in plan] + ([(kind, dy, True) for kind, dy in plan] if p.ground_contacts else [])
        for attempt, (kind, dy, contact) in enumerate(plan_all):
            if not np.any(dy):
                continue
            K, C = cons.rows(qh, dy)
            if contact:
                K, C = _with_ground_contacts(energy, qh, dy, K, C, g_hat, scale, p)
                if K.shape[0] == cons.rows(qh, dy)[0].shape[0]:
                    continue  # no contact in the way: the plain attempt already said no
            constrained = K.shape[0] > 0
            if constrained:  # Algorithm 2: project onto the constraints' null space
                dy = _project_constraints(dy, K, C, g_hat, p)
            q_new = tangent_step(m, qh, dy / scale)
            # eq. (13) as a hard bound: the least-squares projection leaves residuals of ~1e-6 rad
            qj = checker.index.qpos_joints
            q_new[qj] = np.clip(q_new[qj], checker.robot.joint_lower, checker.robot.joint_upper)
            valid = checker.is_valid_qpos(q_new)
            if log.isEnabledFor(logging.DEBUG):
                log.debug(
                    "it %d side %d attempt %d %s |dy| %.4f D.g %.3f valid %s E_h %.4g E_new %.4g",
                    it, h, attempt, kind, float(np.linalg.norm(dy)), float(D_hat @ g_hat), valid,
                    evals[h].total, energy(q_new, gradient=False).total,
                )
                if not valid:
                    log.debug("  invalid: %s", "; ".join(checker.check_qpos(q_new).reasons()))
            if valid:
                e_new = energy(q_new)
                # a step must not climb (energy barrier of section 4.2), up to a 0.1 % tolerance
                if e_new.total <= evals[h].total * (1.0 + 1e-3):
                    accepted = True
                    break
            stats["rejected_steps"] += 1
        if not accepted:
            return finish(
                PlanStatus.FAILED,
                f"blocked: no legal energy-non-increasing step from the {'start' if h == 0 else 'goal'} side after {it} iterations",
                None,
            )
        stats[kind] += 1
        stats["constrained_steps"] += int(constrained)
        stats["contact_steps"] += int(contact)
        ends[h] = q_new
        evals[h] = e_new
        glis[h] = gli(q_new)
        paths[h].append(q_new)
        e_low = min(evals[0].total, evals[1].total)
        log.debug("it %d moved %d by %s: E %.4g / %.4g, gap %.3f, E_gli %.3f", it, h, kind, evals[0].total, evals[1].total, gap,
                  gli_difference(glis[0], glis[1]))
        if window.update(e_low, gap, 0.1 * alpha):
            return finish(
                PlanStatus.FAILED,
                f"local minimum (paper 004 section 8): energies {evals[0].total:.4g} / {evals[1].total:.4g} and gap "
                f"{gap:.3f} rad stayed in one window for {p.patience} iterations",
                None,
            )
    return finish(PlanStatus.FAILED, f"no meeting after {p.max_iterations} iterations", None)


def _verified(checker, path, p, levers, finish, stats) -> InterpolationOutcome:
    """Verify every segment of the path at the fine resolution (steps can skip thin contacts)."""
    for k in range(len(path) - 1):
        if not segment_is_valid(checker, path[k], path[k + 1], resolution_m=p.verify_resolution_m, levers=levers):
            return finish(PlanStatus.FAILED, f"verification: segment {k} of {len(path) - 1} is illegal at {p.verify_resolution_m} m", None)
    stats["waypoints"] = len(path)
    return finish(PlanStatus.EXACT_SOLUTION, "", path)


def safe_zone_keyframes(
    checker: ValidityChecker,
    path: np.ndarray,
    gli: GliMatrix,
    *,
    threshold: float = GLI_SAFE_ZONE_THRESHOLD,
    resolution_m: float = ENERGY_VERIFY_RESOLUTION_M,
    levers: tuple[float, np.ndarray] | None = None,
    deadline: float | None = None,
    stats: dict[str, Any] | None = None,
) -> np.ndarray:
    """The key postures of a legal path: consecutive ones linearly interpolable (paper 004 section 5.2).

    Section 5.2: postures of one safe subspace can be linearly interpolated, and "in the output,
    every two consecutive postures are in the same subspace". Algorithm 1 takes steps of alpha,
    alternating direct and projected (eq. 5) steps, so its raw output zig-zags at the step scale.
    From each key posture P_i we keep the farthest later posture P_j of the path (binary search)
    with E_gli(P_i, P_j) < ``threshold`` (eq. 8) whose straight motion the checker also finds
    legal at ``resolution_m``; the path is then P_i -> P_j, ... Deterministic; every kept segment is
    verified, and consecutive raw postures are always kept as a fallback, so the result is legal.

    Args:
        path: a legal path as qpos rows, shape (K, nq).
        deadline: ``time.monotonic()`` value; once passed, the postures after the last key posture
            found are all kept (the raw path's legal segments), so the result is legal but longer.
        stats: filled with ``stopped_on_budget`` (True when the deadline ended the reduction).

    Returns:
        the key postures, shape (K', nq), K' <= K, same first and last row.
    """
    lev = levers if levers is not None else lever_arms(checker)
    mats: dict[int, np.ndarray] = {}
    n = len(path)

    def mat(i: int) -> np.ndarray:
        if i not in mats:
            mats[i] = gli(path[i])
        return mats[i]

    def ok(i: int, j: int) -> bool:
        return gli_difference(mat(i), mat(j)) < threshold and segment_is_valid(checker, path[i], path[j], resolution_m=resolution_m, levers=lev)

    keep = [0]
    i = 0
    stopped = False
    while i < n - 1:
        if _past(deadline):
            stopped = True
            keep.extend(range(i + 1, n))
            break
        lo, hi = i + 1, n - 1  # lo: legal (a verified raw segment)
        if ok(i, hi):
            lo = hi
        while lo < hi and not _past(deadline):
            mid = (lo + hi + 1) // 2
            if ok(i, mid):
                lo = mid
            else:
                hi = mid - 1
        keep.append(lo)
        i = lo
    if stats is not None:
        stats["stopped_on_budget"] = stopped
    return path[keep]


def _limb_dofs(checker: ValidityChecker) -> list[tuple[str, np.ndarray]]:
    """(name, qvel indices) of the root and of the five linkages of paper 004 Fig. 8 (robot.toml [limbs])."""
    robot = checker.robot
    dof = np.asarray(checker.index.dof_joints)
    out = [("root", np.asarray(checker.index.qvel_root))]
    for name in LINKAGE_ORDER:
        out.append((name, np.array([dof[robot.joint_index(j)] for j in robot.limbs.get(name, ())], dtype=int)))
    return [(n, d) for n, d in out if d.size]


def straighten_limbs(
    checker: ValidityChecker,
    path: np.ndarray,
    *,
    resolution_m: float = ENERGY_VERIFY_RESOLUTION_M,
    levers: tuple[float, np.ndarray] | None = None,
    root_translation_scale_m: float = ROOT_TRANSLATION_SCALE_M,
    deadline: float | None = None,
    stats: dict[str, Any] | None = None,
) -> np.ndarray:
    """Undo the expansion of the root and of each linkage that the problem does not need.

    Paper 004 section 5.1: the energy "expands all parts almost equally", so "some unnecessary
    expansion still happens especially at the peripheral joints" (its remedy is the fall-off d).
    On a lying robot this moves the legs for an arm problem (crossed arms: hip roll +-0.26 rad and
    back) and the root, and every moving joint adds to the motion's jerk. Here, in turn for the
    root and the five linkages of Fig. 8 (torso, left arm, right arm, left leg, right leg), the
    part's coordinates in every interior key posture are replaced by the straight motion from its
    start to its end value (at the posture's arc-length fraction along the path, in the scaled
    tangent chart of the first posture), and the change is kept if every posture and every
    segment stays legal at ``resolution_m``. Deterministic; the ends do not change; the result is
    legal wherever the input is.

    Args:
        path: legal key postures as qpos rows, shape (K, nq).
        deadline: ``time.monotonic()`` value; once passed, the remaining parts are left as they are.
        stats: filled with ``straightened``: the names of the parts made straight, and
            ``stopped_on_budget`` (True when the deadline left parts untried).

    Returns:
        qpos rows, shape (K, nq).
    """
    m = checker.model
    lev = levers if levers is not None else lever_arms(checker)
    scale = _tangent_scale(checker, root_translation_scale_m)
    q = np.array(path, dtype=float)
    done: list[str] = []
    stopped = False
    if len(q) > 2:
        qj = checker.index.qpos_joints
        lo, hi = checker.robot.joint_lower, checker.robot.joint_upper
        for name, dofs in _limb_dofs(checker):
            if _past(deadline):
                stopped = True
                break
            y = np.array([tangent_difference(m, q[0], x) for x in q])
            seg = np.linalg.norm(np.diff(scale * y, axis=0), axis=1)
            u = np.concatenate([[0.0], np.cumsum(seg)]) / max(float(seg.sum()), 1e-12)
            cand_y = y.copy()
            cand_y[1:-1, dofs] = u[1:-1, None] * y[-1, dofs][None, :]
            if np.max(np.abs(cand_y - y)) < 1e-9:
                continue
            cand = np.array([tangent_step(m, q[0], v) for v in cand_y])
            cand[:, qj] = np.clip(cand[:, qj], lo, hi)
            cand[0], cand[-1] = q[0], q[-1]
            if all(checker.is_valid_qpos(x) for x in cand[1:-1]) and all(
                segment_is_valid(checker, a, b, resolution_m=resolution_m, levers=lev) for a, b in zip(cand[:-1], cand[1:])
            ):
                q = cand
                done.append(name)
    if stats is not None:
        stats["straightened"] = done
        stats["stopped_on_budget"] = stopped
    return q



# --- second stage (section 6.2) -------------------------------------------------------------------


def resample_path(checker: ValidityChecker, path: np.ndarray, spacing_rad: float, scale: np.ndarray | None = None) -> np.ndarray:
    """A polyline of qpos rows with every segment cut into equal parts at most ``spacing_rad`` long.

    Lengths are scaled tangent-space norms (``_tangent_scale``). The original rows are all kept and
    the new ones lie on the straight tangent motions between them, so the result traces the same
    motion (and is legal wherever the input's segments are).

    Args:
        path: qpos rows, shape (K, nq), K >= 1.

    Returns:
        qpos rows, shape (K', nq), K' >= K, same first and last row.
    """
    m = checker.model
    sc = scale if scale is not None else _tangent_scale(checker)
    out = [np.array(path[0], dtype=float)]
    for a, b in zip(path[:-1], path[1:]):
        v = tangent_difference(m, a, b)
        n = max(1, int(math.ceil(float(np.linalg.norm(sc * v)) / spacing_rad)))
        out.extend(tangent_step(m, a, v * (k / n)) for k in range(1, n))
        out.append(np.array(b, dtype=float))
    return np.array(out)


def trajectory_laplacian_energy(checker: ValidityChecker, path: np.ndarray, scale: np.ndarray | None = None) -> float:
    """Sum over interior frames of 1/2 |y_(t-1) - 2 y_t + y_(t+1)|^2, y the scaled tangent chart at the first frame [rad^2]."""
    sc = scale if scale is not None else _tangent_scale(checker)
    y = np.array([sc * tangent_difference(checker.model, path[0], q) for q in path])
    if len(y) < 3:
        return 0.0
    d2 = y[:-2] - 2.0 * y[1:-1] + y[2:]
    return 0.5 * float(np.sum(d2 * d2))


def _second_difference(n: int) -> Any:
    """The (n - 2, n) second-difference operator (rows 1, -2, 1) as a sparse matrix."""
    from scipy import sparse

    if n < 3:
        return sparse.csr_matrix((0, n))
    rows = np.repeat(np.arange(n - 2), 3)
    cols = (np.arange(n - 2)[:, None] + np.arange(3)[None, :]).ravel()
    vals = np.tile([1.0, -2.0, 1.0], n - 2)
    return sparse.csr_matrix((vals, (rows, cols)), shape=(n - 2, n))


class _CoM:
    """Robot CoM and its Jacobian in the scaled tangent chart of a reference posture (eq. 18)."""

    def __init__(self, checker: ValidityChecker, scale: np.ndarray, q_ref: np.ndarray) -> None:
        self.m = checker.model
        self.d = mujoco.MjData(self.m)
        self.scale = scale
        self.root_ang = np.asarray(checker.index.qvel_root)[3:6]
        jnt = int(np.flatnonzero(self.m.jnt_type == int(mujoco.mjtJoint.mjJNT_FREE))[0])
        self.body = int(self.m.jnt_bodyid[jnt])
        self.adr = int(self.m.jnt_qposadr[jnt])
        self.r_ref = self._rot(q_ref)
        self.jac = np.zeros((3, self.m.nv))

    def _rot(self, q: np.ndarray) -> np.ndarray:
        r = np.zeros(9)
        mujoco.mju_quat2Mat(r, np.asarray(q[self.adr + 3 : self.adr + 7], dtype=float))
        return r.reshape(3, 3)

    def __call__(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """CoM [units of ROOT_TRANSLATION_SCALE_M], shape (3,), and d CoM / d y, shape (3, nv)."""
        m, d = self.m, self.d
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_jacSubtreeCom(m, d, self.jac, self.body)
        s_root = self.scale[0]  # 1 / ROOT_TRANSLATION_SCALE_M on the root translation rows
        jac = self.jac * s_root
        # the chart's root rotation is in the reference root frame, qvel's in the current one
        a = self.root_ang
        jac[:, a] = jac[:, a] @ (self._rot(q).T @ self.r_ref)
        return d.subtree_com[self.body] * s_root, jac / self.scale[None, :]


def second_stage(
    checker: ValidityChecker,
    path: np.ndarray,
    *,
    params: SecondStageParams = SecondStageParams(),
    constraints: tuple[PositionalConstraint, ...] = (),
    resolution_m: float = ENERGY_VERIFY_RESOLUTION_M,
    root_translation_scale_m: float = ROOT_TRANSLATION_SCALE_M,
    deadline: float | None = None,
    stats: dict[str, Any] | None = None,
) -> np.ndarray:
    """Project a legal first-stage motion onto the constraint manifold of paper 004 section 6.2.

    The motion (``path``, resampled by ``resample_path`` to frames ``frame_spacing_rad`` apart)
    is written in the scaled tangent chart y of its first frame. Each iteration solves the
    quadratic problem of eq. (19) with M = I for the frame changes dy (end frames fixed):

        min 1/2 sum_t |dy_t|^2 + w_lap/2 sum_t |Lap(y + dy)_t|^2 + w_lm/2 sum_t |Lap(c + J_c dy)_t|^2

    i.e. the linear system of eq. (20) (sparse, banded), where Lap is the second difference
    over frames (the trajectory Laplacian: with frames at equal time steps, the change of velocity)
    and c_t the robot's CoM with its Jacobian J_c (the linear-momentum deviation of eq. 18, at
    equal time steps m (v_t - v_(t+1)) ~ m Lap(c)_t). Joint limits (eq. 13) and positional
    constraints (eq. 12) are hard: each frame's change is projected by eq. (10)-(11) and clipped to
    the joint bounds. No new penetrations: the paper relies on its (spatial) Laplacian energy for
    that; we ask the validity checker. A frame whose new posture, or a segment next to it at
    ``resolution_m``, is illegal has its change halved (``halvings`` times) and then keeps its
    previous posture, so every iteration's motion is legal. The spatial Laplacian of eq. (15)-(16)
    and the angular momentum of eq. (17) are not used.

    Args:
        path: a legal motion (every row legal, every straight segment legal at ``resolution_m``),
            qpos rows, shape (K, nq).
        deadline: ``time.monotonic()`` value checked before each iteration; once passed, the
            motion of the last finished iteration is returned (legal, less smooth).
        stats: filled with frames, iterations (finished ones), held (frame changes refused),
            Laplacian energy before / after and ``stopped_on_budget`` (True when the deadline
            ended the iterations).

    Returns:
        the projected motion, qpos rows, shape (K', nq): same first and last row, legal at
        ``resolution_m``.
    """
    from scipy import sparse
    from scipy.sparse.linalg import spsolve

    m = checker.model
    scale = _tangent_scale(checker, root_translation_scale_m)
    ep = EnergyParams()  # eq. (10)-(11)'s damping and energy step (the defaults)
    levers = lever_arms(checker)
    q = resample_path(checker, np.asarray(path, dtype=float), params.frame_spacing_rad, scale)
    n, nv = len(q), int(m.nv)
    st = stats if stats is not None else {}
    st.update(frames=n, iterations=0, held=0, stopped_on_budget=False, laplacian_before=trajectory_laplacian_energy(checker, q, scale))
    if n < 3 or params.iterations == 0:
        st["laplacian_after"] = st["laplacian_before"]
        return q
    q_ref = q[0].copy()
    cons = _Constraints(checker, constraints, scale)
    com = _CoM(checker, scale, q_ref)
    qj = checker.index.qpos_joints
    lo, hi = checker.robot.joint_lower, checker.robot.joint_upper
    D = _second_difference(n)
    inner = slice(1, n - 1)
    DtD = (D.T @ D).tocsr()
    A_lap = sparse.kron(DtD[inner, inner], sparse.identity(nv), format="csr")

    def seg_ok(a: np.ndarray, b: np.ndarray) -> bool:
        return segment_is_valid(checker, a, b, resolution_m=resolution_m, levers=levers)

    for it in range(params.iterations):
        if _past(deadline):  # every finished iteration's motion is legal: stop between two
            st["stopped_on_budget"] = True
            break
        st["iterations"] = it + 1
        y = np.array([scale * tangent_difference(m, q_ref, x) for x in q])  # (n, nv)
        rhs = -params.w_lap * (DtD @ y)[inner].ravel()
        A = sparse.identity((n - 2) * nv, format="csr") + params.w_lap * A_lap
        if params.w_lm > 0.0:
            cj = [com(x) for x in q]
            c = np.array([v for v, _ in cj])
            # G: (n - 2) blocks of 3 rows; block i = J_i - 2 J_(i+1) + J_(i+2), interior frames only
            gr, gc, gv = [], [], []
            for i in range(n - 2):
                for k, w in zip(range(i, i + 3), (1.0, -2.0, 1.0)):
                    if 1 <= k <= n - 2:
                        gr.append(np.repeat(3 * i + np.arange(3), nv))
                        gc.append(np.tile((k - 1) * nv + np.arange(nv), 3))
                        gv.append((w * cj[k][1]).ravel())
            G = sparse.csr_matrix((np.concatenate(gv), (np.concatenate(gr), np.concatenate(gc))), shape=(3 * (n - 2), (n - 2) * nv))
            r = (D @ c).ravel()
            A = A + params.w_lm * (G.T @ G)
            rhs = rhs - params.w_lm * (G.T @ r)
        dy = np.zeros((n, nv))
        dy[inner] = np.asarray(spsolve(A.tocsc(), rhs)).reshape(n - 2, nv)
        # the change of each frame as a step in its own tangent space (the chart's root rotation is
        # in the reference frame), projected on the hard constraints (eq. 10-11, 13)
        step = np.zeros((n, nv))
        for t in range(1, n - 1):
            target = tangent_step(m, q_ref, (y[t] + dy[t]) / scale)
            step[t] = scale * tangent_difference(m, q[t], target)
            K, C = cons.rows(q[t], step[t])
            if K.shape[0]:
                step[t] = _project_constraints(step[t], K, C, np.zeros(nv), ep)
        f = np.ones(n)
        f[0] = f[-1] = 0.0
        cand = q.copy()
        changed = f > 0  # frames whose candidate posture is new this round: only their checks can change
        for rnd in range(params.halvings + 2):
            for t in np.flatnonzero(changed):
                cand[t] = tangent_step(m, q[t], step[t] * f[t] / scale) if f[t] > 0 else q[t]
                cand[t, qj] = np.clip(cand[t, qj], lo, hi)
            bad = np.array([bool(changed[t] and f[t] > 0 and not checker.is_valid_qpos(cand[t])) for t in range(n)])
            for t in range(n - 1):
                if (changed[t] or changed[t + 1]) and (f[t] > 0 or f[t + 1] > 0) and not seg_ok(cand[t], cand[t + 1]):
                    bad[t] |= f[t] > 0
                    bad[t + 1] |= f[t + 1] > 0
            if not bad.any():
                break
            f[bad] = 0.0 if rnd >= params.halvings else 0.5 * f[bad]
            changed = bad
        else:  # refusals in the last round: keep the previous motion, which is legal
            cand = q
            f[:] = 0.0
        st["held"] += int(np.sum(f[1:-1] == 0.0))
        moved = float(np.max(np.abs(scale * np.array([tangent_difference(m, a, b) for a, b in zip(q, cand)]))))
        q = cand
        if moved < params.tolerance_rad:
            break
    st["laplacian_after"] = trajectory_laplacian_energy(checker, q, scale)
    return q

def _bspline_chart(checker: ValidityChecker, path: np.ndarray, per_piece: int) -> np.ndarray:
    """Samples of the uniform cubic B-spline of the rows (ends tripled: it starts and ends on them),
    in the tangent chart of the first row; ``per_piece`` samples per piece; qpos rows (K', nq)."""
    m = checker.model
    y = np.array([tangent_difference(m, path[0], x) for x in path])
    c = np.concatenate([y[:1], y[:1], y, y[-1:], y[-1:]])
    pieces = len(c) - 3
    u = np.arange(per_piece) / per_piece
    b = np.stack([(1 - u) ** 3, 3 * u**3 - 6 * u**2 + 4, -3 * u**3 + 3 * u**2 + 3 * u + 1, u**3], axis=1) / 6.0
    ys = [b @ c[j : j + 4] for j in range(pieces)]  # piece 0 starts on the first row, the last ends on the last
    out = np.array([path[0]] + [tangent_step(m, path[0], v) for v in np.concatenate(ys)[1:]] + [path[-1]])
    qj = checker.index.qpos_joints
    out[:, qj] = np.clip(out[:, qj], checker.robot.joint_lower, checker.robot.joint_upper)
    return out


def _timed_roughness(checker: ValidityChecker, path: np.ndarray) -> float:
    """J x D^5 [rad^2] of the shared servo-limited timing of qpos rows: the jerk at a common duration."""
    robot = checker.robot
    seq = PostureSequence.from_postures([posture_from_qpos(robot, checker.index, q) for q in path], robot.joint_names)
    timed = time_parameterize(seq, robot)
    return integrated_squared_jerk(timed.t, timed.joints) * timed.duration_s**5


def dense_output(
    checker: ValidityChecker,
    path: np.ndarray,
    *,
    spacing_rad: float = OUTPUT_SPACING_RAD,
    resolution_m: float = ENERGY_VERIFY_RESOLUTION_M,
    levers: tuple[float, np.ndarray] | None = None,
    root_translation_scale_m: float = ROOT_TRANSLATION_SCALE_M,
    deadline: float | None = None,
    stats: dict[str, Any] | None = None,
) -> np.ndarray:
    """The second stage's motion written out densely, so that the shared timing sees its shape.

    The shared timing (timing.py) caps the speed at each knot by the change of direction there;
    frames ``frame_spacing_rad`` apart, densified linearly by the timing or the smoother's curve
    into 2-3 steps each, make a bend every few knots and the speed oscillates (issue 7:
    arm under the back, J x D^5 11x that of the same frames written 5x denser). Two dense
    versions of the frames, both ``spacing_rad`` apart or closer (scaled tangent norm):

    - the frames' polyline resampled (``resample_path``): legal, as the frames' segments are;
    - the uniform cubic B-spline of the frames (C2: no bend at the frames), kept only if every
      sample and segment is legal at ``resolution_m``.

    The one whose shared timing has the lower jerk at a common duration (J x D^5) is returned.

    Args:
        path: a legal motion, qpos rows, shape (K, nq).
        deadline: ``time.monotonic()`` value; once passed (while the curve is checked or before
            the two are timed), the polyline is returned.
        stats: filled with ``output`` ("polyline" or "bspline"), ``output_frames`` and
            ``stopped_on_budget`` (True when the deadline left the curve unchecked or untimed).

    Returns:
        qpos rows, shape (K', nq), K' >= K, same first and last row.
    """
    lev = levers if levers is not None else lever_arms(checker)
    scale = _tangent_scale(checker, root_translation_scale_m)
    m = checker.model
    path = np.asarray(path, dtype=float)
    poly = resample_path(checker, path, spacing_rad, scale)
    out, kind = poly, "polyline"
    stopped = False
    if len(path) > 2:
        gaps = [float(np.linalg.norm(scale * tangent_difference(m, a, b))) for a, b in zip(path[:-1], path[1:])]
        spline = _bspline_chart(checker, path, max(1, int(math.ceil(max(gaps) / spacing_rad))))
        legal = True
        for k in range(1, len(spline)):  # sample k and the segment that ends there (the last sample is the path's)
            if _past(deadline):
                legal, stopped = False, True
                break
            if (k < len(spline) - 1 and not checker.is_valid_qpos(spline[k])) or not segment_is_valid(
                checker, spline[k - 1], spline[k], resolution_m=resolution_m, levers=lev
            ):
                legal = False
                break
        if legal and _past(deadline):
            legal, stopped = False, True
        if legal and _timed_roughness(checker, spline) < _timed_roughness(checker, poly):
            out, kind = spline, "bspline"
    if stats is not None:
        stats.update(output=kind, output_frames=len(out), stopped_on_budget=stopped)
    return out



def _refine_leg(
    checker: ValidityChecker,
    q_leg: np.ndarray,
    gli: GliMatrix,
    params: EnergyParams,
    constraints: tuple[PositionalConstraint, ...],
    deadline: float,
    leg_stats: dict[str, Any],
) -> np.ndarray:
    """One leg's legal first-stage motion reduced and smoothed as ``params`` asks, within ``deadline``.

    Key postures, straightening, second stage and dense output in turn, each legal wherever its
    input is; ``leg_stats`` gets their counters and ``stopped_on_budget``, the steps that the
    deadline cut short (an empty list when none). Returns qpos rows, shape (K', nq).
    """
    stopped: list[str] = []
    res = params.verify_resolution_m
    if params.keyframes and len(q_leg) > 2:
        s: dict[str, Any] = {}
        q_leg = safe_zone_keyframes(checker, q_leg, gli, threshold=params.gli_threshold, resolution_m=res, deadline=deadline, stats=s)
        leg_stats["key_postures"] = len(q_leg)
        if s["stopped_on_budget"]:
            stopped.append("key postures")
    if params.straighten_limbs and len(q_leg) > 2:
        s = {}
        q_leg = straighten_limbs(checker, q_leg, resolution_m=res, root_translation_scale_m=params.root_translation_scale_m,
                                 deadline=deadline, stats=s)
        leg_stats["straightened"] = s["straightened"]
        if s["stopped_on_budget"]:
            stopped.append("straightening")
    if params.second_stage is not None and len(q_leg) > 1:
        s2: dict[str, Any] = {}
        q_leg = second_stage(checker, q_leg, params=params.second_stage, constraints=constraints, resolution_m=res,
                             root_translation_scale_m=params.root_translation_scale_m, deadline=deadline, stats=s2)
        leg_stats["second_stage"] = s2
        if s2["stopped_on_budget"]:
            stopped.append("second stage")
        if params.dense_output:
            s = {}
            q_leg = dense_output(checker, q_leg, resolution_m=res, root_translation_scale_m=params.root_translation_scale_m,
                                 deadline=deadline, stats=s)
            s2.update(output=s["output"], output_frames=s["output_frames"])
            if s["stopped_on_budget"]:
                stopped.append("dense output")
    leg_stats["stopped_on_budget"] = stopped
    return q_leg


def plan_energy(
    problem: PlanningProblem,
    *,
    params: EnergyParams = EnergyParams(),
    constraints: tuple[PositionalConstraint, ...] = (),
    retry_falloffs: tuple[int, ...] = FALLOFF_RETRY_SCHEDULE,
) -> PlanResult:
    """The energy-driven planner behind the shared interface: ``plan_energy(problem) -> PlanResult``.

    Plans start -> goal (through ``problem.key`` when given, as two legs) with
    ``energy_interpolate``. Local minima depend on the fall-off exponent d (paper 004 section 8),
    so after a FAILED leg the other exponents of ``retry_falloffs`` are tried in turn within the
    budget. Once every leg has its legal first-stage motion, each is reduced and smoothed
    (key postures, straightening, second stage, dense output) in what is left of
    ``problem.budget_s``: each of those steps only ever replaces a legal motion by another legal
    one, so when the budget runs out they stop where they are and the motion is returned legal
    but less smooth (``stats["stopped_on_budget"]`` names the steps cut short, and a warning is
    logged). Deterministic while the budget is not reached: ``problem.seed`` is not used.

    Returns:
        PlanResult with a PostureSequence path on success, or a status and a reason.
    """
    checker = problem.checker
    robot = checker.robot
    t0 = time.monotonic()
    deadline = t0 + problem.budget_s
    gli = GliMatrix(robot, checker.model, checker.index)
    schedule = [params.falloff_d] + [d for d in retry_falloffs if d != params.falloff_d]
    energies: dict[int, RepulsiveEnergy] = {}
    legs = [problem.start, problem.goal] if problem.key is None else [problem.start, problem.key, problem.goal]
    first: list[tuple[np.ndarray, dict[str, Any]]] = []  # each leg's first-stage motion and its stats
    stats: dict[str, Any] = {"planner": "energy", "legs": []}
    for k in range(len(legs) - 1):
        reasons = []
        out = None
        for d in schedule:
            remaining = problem.budget_s - (time.monotonic() - t0)
            if remaining <= 0.0:
                break
            p_d = dataclasses.replace(params, falloff_d=d)
            if d not in energies:
                energies[d] = RepulsiveEnergy(checker, p_d)
            out = energy_interpolate(
                checker,
                checker.qpos_of(legs[k]),
                checker.qpos_of(legs[k + 1]),
                params=p_d,
                constraints=constraints,
                budget_s=remaining,
                energy=energies[d],
                gli=gli,
            )
            out.stats["falloff_d"] = d
            stats["legs"].append(out.stats)
            if out.status is not PlanStatus.FAILED:
                break
            reasons.append(f"d={d}: {out.reason}")
            log.info("energy planner, leg %d, d=%d failed: %s", k, d, out.reason)
        if out is None:
            out = InterpolationOutcome(PlanStatus.TIMEOUT, None, f"budget of {problem.budget_s:.1f} s spent")
        if out.status is not PlanStatus.EXACT_SOLUTION or out.qpos is None:
            status = out.status
            if status is PlanStatus.INVALID_GOAL and problem.key is not None and k == 0:
                status = PlanStatus.FAILED  # an illegal key posture: not the goal's fault
            reason = "; ".join(reasons) if status is PlanStatus.FAILED and reasons else out.reason
            stats["seconds"] = time.monotonic() - t0
            return PlanResult(status, None, f"leg {k}: {reason}" if len(legs) > 2 else reason, stats)
        first.append((out.qpos, out.stats))
    rows: list[np.ndarray] = []
    stopped: list[str] = []
    for k, (q_leg, leg_stats) in enumerate(first):
        q_leg = _refine_leg(checker, q_leg, gli, params, constraints, deadline, leg_stats)
        stopped += [f"leg {k}: {step}" if len(first) > 1 else step for step in leg_stats["stopped_on_budget"]]
        rows.extend(q_leg if k == 0 else q_leg[1:])
    stats["stopped_on_budget"] = stopped
    if stopped:
        log.warning("energy planner: budget of %.3g s reached in %s; returning the legal motion as it stood (less smooth)",
                    problem.budget_s, ", ".join(stopped))
    stats["seconds"] = time.monotonic() - t0
    stats["waypoints"] = len(rows)
    postures: list[Posture] = [posture_from_qpos(robot, checker.index, q) for q in rows]
    path = PostureSequence.from_postures(postures, robot.joint_names)
    return PlanResult(PlanStatus.EXACT_SOLUTION, path, "", stats)


@dataclass(frozen=True)
class EnergyPlanner:
    """``plan_energy`` as a ``Planner`` object (for ``plan_trajectory(problem, planner=...)``)."""

    params: EnergyParams = EnergyParams()
    constraints: tuple[PositionalConstraint, ...] = ()

    def __call__(self, problem: PlanningProblem) -> PlanResult:
        return plan_energy(problem, params=self.params, constraints=self.constraints)
