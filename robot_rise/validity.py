"""Validity of postures for planning: joint limits, ground, self and obstacle collision.

One question, one owner (OMPL's StateValidityChecker): the checker answers "is this posture
legal?" and "how far from the nearest contact is it?", nothing about paths. Collision geometry
is the robot's geoms as the model defines them (the OP3's capsules/boxes, paper 000 section
4.2.2, sphere-swept volumes; a mesh is its convex hull, as MuJoCo collides it) and the scene's
world geoms; MuJoCo's collision pipeline computes signed distances and decides which pairs can
collide (contype/conaffinity, ``<contact><exclude>``, parent bodies: ``robot_rise.geometry``).

Joint limits are strict (float rounding aside): a posture slightly past a limit, as a servo
resting on its stop reads, is clamped where it enters the product (``posture.admit_posture``:
posture files, trajectory starts, the start of ``rise``), never here.

Touching is legal: a contact counts as a collision only when the surfaces interpenetrate by
more than ``contact_tolerance_m`` (a lying robot touches the ground everywhere it rests).

Looseness (paper 000 section 4.2.3): the ground can be lowered and obstacles shrunk so that a
planner can start from a relaxed problem and tighten it to the real one.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import mujoco
import numpy as np

from robot_rise.geometry import collision_mask, colliding_geoms, lowest_point_z, mesh_hulls
from robot_rise.model import ModelIndex, Robot, compose, model_index
from robot_rise.posture import Posture
from robot_rise.linkage import close_loops

__all__ = ["Looseness", "STRICT", "Collision", "ValidityReport", "ValidityChecker", "CollisionKind", "DEFAULT_CONTACT_TOLERANCE_M"]

DEFAULT_CONTACT_TOLERANCE_M = 0.002  # interpenetration allowed as "touching" (MuJoCo soft contact)
DEFAULT_CLEARANCE_MARGIN_M = 0.05  # distances are measured up to this; beyond, clearance reads as this
JOINT_LIMIT_ROUNDING_RAD = 1e-6  # past a joint limit still inside it: float rounding only (inputs are clamped on entry) [rad]
MIN_OBSTACLE_SIZE_M = 1e-4  # an obstacle shrunk "to zero" keeps this size (MuJoCo needs > 0)

CollisionKind = str  # "ground" | "self" | "obstacle"


@dataclass(frozen=True)
class Looseness:
    """How much the environment is relaxed (paper 000 section 4.2.3).

    Attributes:
        ground_drop_m: ground geoms moved down by this much [m].
        obstacle_shrink_m: every obstacle geom size (radius / half-extent) reduced by this much [m],
            down to a minimum of 0.1 mm ("shrunk to zero").
    """

    ground_drop_m: float = 0.0
    obstacle_shrink_m: float = 0.0

    @property
    def is_strict(self) -> bool:
        return self.ground_drop_m == 0.0 and self.obstacle_shrink_m == 0.0


STRICT = Looseness()


@dataclass(frozen=True)
class Collision:
    """One interpenetrating pair. ``distance_m`` is negative (penetration depth)."""

    kind: CollisionKind
    geom1: str
    geom2: str
    distance_m: float


@dataclass(frozen=True)
class ValidityReport:
    """Full validity report of one posture.

    Clearances are signed minimum distances per pair class [m]: negative is penetration; values
    saturate at the checker's clearance margin (nothing nearer than that).
    """

    valid: bool
    limit_violations: tuple[str, ...]
    ground_clearance_m: float
    self_clearance_m: float
    obstacle_clearance_m: float
    collisions: tuple[Collision, ...] = field(default_factory=tuple)

    @property
    def ground_penetration(self) -> bool:
        return any(c.kind == "ground" for c in self.collisions)

    @property
    def self_collision(self) -> bool:
        return any(c.kind == "self" for c in self.collisions)

    @property
    def obstacle_collision(self) -> bool:
        return any(c.kind == "obstacle" for c in self.collisions)

    def reasons(self) -> list[str]:
        """One line per problem, empty when valid."""
        out = [f"joint limit: {v}" for v in self.limit_violations]
        out += [f"{c.kind} collision: {c.geom1} / {c.geom2} penetrate {-c.distance_m * 1000:.1f} mm" for c in self.collisions]
        return out


class ValidityChecker:
    """Checks postures of one robot in one scene at one looseness.

    Not thread-safe (owns one MjData); make one per thread.
    """

    def __init__(
        self,
        robot: Robot,
        scene: str | os.PathLike[str] | None = "flat",
        *,
        looseness: Looseness = STRICT,
        contact_tolerance_m: float = DEFAULT_CONTACT_TOLERANCE_M,
        clearance_margin_m: float = DEFAULT_CLEARANCE_MARGIN_M,
        joint_limit_tolerance_rad: float = JOINT_LIMIT_ROUNDING_RAD,
        _base: mujoco.MjModel | None = None,
    ) -> None:
        self.robot = robot
        self.scene = scene
        self.looseness = looseness
        self.contact_tolerance_m = float(contact_tolerance_m)
        self.clearance_margin_m = float(clearance_margin_m)
        self.joint_limit_tolerance_rad = float(joint_limit_tolerance_rad)
        base = _base if _base is not None else compose(robot, scene, with_actuators=False)
        self._base = base
        self.model = _loosened_copy(base, robot, looseness)
        self.index: ModelIndex = model_index(self.model, robot)
        self._data = mujoco.MjData(self.model)
        self._probe_model = _loosened_copy(base, robot, looseness)
        self._probe_model.geom_margin[:] = self.clearance_margin_m
        # The midphase's bounding boxes of a body with several geoms (the world's obstacles, a
        # robot link of many geoms) were sized at compile time without this margin: it would drop
        # pairs within the margin but not touching, and their clearance would read as the cap.
        self._probe_model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_MIDPHASE)
        self._probe_data = mujoco.MjData(self._probe_model)
        self._lower = robot.joint_lower - self.joint_limit_tolerance_rad
        self._upper = robot.joint_upper + self.joint_limit_tolerance_rad
        self._qj = self.index.qpos_joints
        qj = self._qj
        contiguous = len(qj) > 0 and np.array_equal(qj, np.arange(qj[0], qj[0] + len(qj)))
        self._qj_slice: slice | np.ndarray = slice(int(qj[0]), int(qj[0]) + len(qj)) if contiguous else qj
        self._mid = (self._lower + self._upper) / 2
        self._half = (self._upper - self._lower) / 2
        self._geom_kind = self.index.geom_kind  # 0 robot, 1 ground, 2 obstacle
        self._geom_names = [self.model.geom(g).name or f"geom{g}" for g in range(self.model.ngeom)]
        # what the robot rests on the ground with: geoms that can touch the ground (any geom if no ground)
        mask = collision_mask(self.model)
        ground = self.index.ground_geoms if len(self.index.ground_geoms) else None
        self._resting_geoms = colliding_geoms(mask, self.index.robot_geoms, ground)
        self._hulls = mesh_hulls(self.model, self._resting_geoms)

    # --- construction helpers -----------------------------------------------------------------

    def loosened(self, looseness: Looseness) -> ValidityChecker:
        """A checker for the same robot and scene at another looseness (shares the base model)."""
        return ValidityChecker(
            self.robot,
            self.scene,
            looseness=looseness,
            contact_tolerance_m=self.contact_tolerance_m,
            clearance_margin_m=self.clearance_margin_m,
            joint_limit_tolerance_rad=self.joint_limit_tolerance_rad,
            _base=self._base,
        )

    @property
    def nq(self) -> int:
        return self.model.nq

    def qpos_of(self, posture: Posture) -> np.ndarray:
        """Posture -> qpos of this checker's model, shape (nq,)."""
        return posture.qpos(self.robot, self.index, self.model.qpos0)

    def _kinematics(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        """Forward kinematics of ``d.qpos``, a closed linkage's passive joints solved first."""
        if self.index.linkage is not None:
            close_loops(m, d, self.index.linkage)  # leaves the kinematics computed
        else:
            mujoco.mj_kinematics(m, d)

    # --- checks -------------------------------------------------------------------------------

    def is_valid_qpos(self, qpos: np.ndarray) -> bool:
        """Fast predicate: limits kept and nothing interpenetrates beyond the tolerance."""
        # One fused comparison on a slice view: numpy call overhead dominates at this size.
        if (np.abs(qpos[self._qj_slice] - self._mid) > self._half).any():
            return False
        m, d = self.model, self._data
        d.qpos[:] = qpos
        self._kinematics(m, d)
        mujoco.mj_collision(m, d)
        n = d.ncon
        if n == 0:
            return True
        return bool(d.contact.dist[:n].min() >= -self.contact_tolerance_m)

    def is_valid(self, posture: Posture) -> bool:
        """Fast predicate for a Posture."""
        return self.is_valid_qpos(self.qpos_of(posture))

    def valid_batch(self, qpos: np.ndarray) -> np.ndarray:
        """Predicate over a batch, qpos shape (N, nq) -> bool array shape (N,)."""
        qpos = np.atleast_2d(qpos)
        return np.fromiter((self.is_valid_qpos(q) for q in qpos), dtype=bool, count=len(qpos))

    def first_invalid(self, qpos: np.ndarray) -> int:
        """Index of the first invalid row of a (N, nq) batch, or -1 if all are valid."""
        for i, q in enumerate(np.atleast_2d(qpos)):
            if not self.is_valid_qpos(q):
                return i
        return -1

    def check_qpos(self, qpos: np.ndarray) -> ValidityReport:
        """Full report for one qpos: limit violations, collisions, clearance per pair class."""
        qpos = np.asarray(qpos, dtype=float)
        qj = qpos[self._qj]
        viol = []
        lo, hi = self.robot.joint_lower, self.robot.joint_upper
        for i in np.flatnonzero((qj < self._lower) | (qj > self._upper)):
            past_mrad = 1e3 * max(lo[i] - qj[i], qj[i] - hi[i])
            viol.append(f"{self.robot.joint_names[i]}={qj[i]:.4f} not in [{lo[i]:.4f}, {hi[i]:.4f}] ({past_mrad:.2f} mrad past)")
        m, d = self._probe_model, self._probe_data
        d.qpos[:] = qpos
        self._kinematics(m, d)
        mujoco.mj_collision(m, d)
        clear = {"ground": self.clearance_margin_m, "self": self.clearance_margin_m, "obstacle": self.clearance_margin_m}
        deepest: dict[tuple[int, int], Collision] = {}  # one entry per geom pair, its deepest contact
        kind_of = self._geom_kind
        for k in range(d.ncon):
            c = d.contact[k]
            g1, g2 = int(c.geom[0]), int(c.geom[1])
            k1, k2 = kind_of[g1], kind_of[g2]
            kind = "self" if k1 == 0 and k2 == 0 else "ground" if 1 in (k1, k2) else "obstacle"
            dist = float(c.dist)
            clear[kind] = min(clear[kind], dist)
            if dist < -self.contact_tolerance_m and (
                (g1, g2) not in deepest or dist < deepest[(g1, g2)].distance_m
            ):
                deepest[(g1, g2)] = Collision(kind, self._geom_names[g1], self._geom_names[g2], dist)
        collisions = sorted(deepest.values(), key=lambda c: c.distance_m)
        return ValidityReport(
            valid=not viol and not collisions,
            limit_violations=tuple(viol),
            ground_clearance_m=clear["ground"],
            self_clearance_m=clear["self"],
            obstacle_clearance_m=clear["obstacle"],
            collisions=tuple(collisions),
        )

    def check(self, posture: Posture) -> ValidityReport:
        """Full report for a Posture."""
        return self.check_qpos(self.qpos_of(posture))

    def lowest_point_z(self, qpos: np.ndarray) -> float:
        """Lowest z of the robot's collision geometry in this posture [m]: exact, meshes by their hulls."""
        d = self._data
        d.qpos[:] = qpos
        self._kinematics(self.model, d)
        return lowest_point_z(self.model, d, self._resting_geoms, self._hulls)


def _loosened_copy(base: mujoco.MjModel, robot: Robot, looseness: Looseness) -> mujoco.MjModel:
    m = _copy_model(base)
    if looseness.is_strict:
        return m
    idx = model_index(m, robot)
    for g in idx.ground_geoms:
        m.geom_pos[g, 2] -= looseness.ground_drop_m
    for g in idx.obstacle_geoms:
        size = m.geom_size[g]
        t = m.geom_type[g]
        if t == mujoco.mjtGeom.mjGEOM_BOX:
            size[:3] = np.maximum(size[:3] - looseness.obstacle_shrink_m, MIN_OBSTACLE_SIZE_M)
        elif t in (mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_CAPSULE, mujoco.mjtGeom.mjGEOM_CYLINDER):
            # radius shrinks (the SSV radius of the paper); a cylinder's half-length shrinks too
            size[0] = max(size[0] - looseness.obstacle_shrink_m, MIN_OBSTACLE_SIZE_M)
            if t == mujoco.mjtGeom.mjGEOM_CYLINDER:
                size[1] = max(size[1] - looseness.obstacle_shrink_m, MIN_OBSTACLE_SIZE_M)
        elif t == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
            size[:3] = np.maximum(size[:3] - looseness.obstacle_shrink_m, MIN_OBSTACLE_SIZE_M)
    # Poses of world geoms are compile-time constants that kinematics copies, not recomputes:
    # refresh them (and bounding volumes) after moving the ground.
    mujoco.mj_setConst(m, mujoco.MjData(m))
    return m


def _copy_model(m: mujoco.MjModel) -> mujoco.MjModel:
    import copy

    return copy.copy(m)
