"""A measured lying posture made a valid start: joints nudged apart, root lifted, reported.

A robot lying somewhere is by definition a valid start. Our model is not its body: a posture
measured on the robot (joint angles + IMU, :mod:`robot_rise.live.estimate`) can press a thigh a
few millimetres into the model's torso, or sink a few millimetres into the model's floor, where
the real body only touches. :func:`repair_start` moves such a posture the least it can to where
the :class:`~robot_rise.validity.ValidityChecker` finds it valid, and says what it changed:

1. joints past a limit are clamped into it;
2. for every self-colliding geom pair, the driven joints of the kinematic chain between the two
   bodies are nudged in the direction that separates them: the gradient of the pair's
   penetration by central finite differences (MuJoCo's signed geom distance), a Gauss-Newton
   step of at most ``step_rad`` per joint, within the joint limits and at most
   ``max_joint_move_rad`` from the measured angle;
3. the root is lifted until nothing sinks into the ground beyond the tolerance (at most
   ``max_lift_m`` in all).

Every penetration is driven to ``margin_m`` inside the checker's contact tolerance, so the start
is not valid by a hair only. When that is not reached within the bounds the result says so with
status ``FAILED`` and the reasons left: an expected failure is a status, not an exception.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from enum import Enum
from typing import Any

import mujoco
import numpy as np

from robot_rise.linkage import close_loops
from robot_rise.posture import Posture, posture_from_qpos
from robot_rise.validity import ValidityChecker

__all__ = ["RepairConfig", "RepairStatus", "JointMove", "StartRepair", "repair_start"]

log = logging.getLogger(__name__)

MAX_REASONS = 3  # StartRepair.describe names this many of the measured posture's problems
DISTANCE_CAP_M = 0.05  # signed geom distances are computed up to this [m] (pairs are in contact: far more than needed)


@dataclass(frozen=True)
class RepairConfig:
    """Bounds of :func:`repair_start` (ours).

    Attributes:
        margin_m: [m] every penetration is driven this far inside the checker's contact
            tolerance (2 mm by default: a repaired start penetrates at most 1.5 mm).
        step_rad: [rad] largest change of one joint per step.
        max_joint_move_rad: [rad] largest total nudge of one joint (from the measured angle
            clamped into the joint limits): the
            executor's start tolerance is 0.1 rad (``drivers.safety.SafetyLimits``), so a repaired
            start's first target stays within it of where the joints really are.
        max_lift_m: [m] largest total lift of the root.
        max_steps: steps at most (each: one nudge of the joints, one lift of the root).
        fd_step_rad: [rad] finite-difference step of the penetration gradient.
    """

    margin_m: float = 0.0005
    step_rad: float = 0.01
    max_joint_move_rad: float = 0.08
    max_lift_m: float = 0.01
    max_steps: int = 40
    fd_step_rad: float = 0.001

    def __post_init__(self) -> None:
        for name in ("margin_m", "step_rad", "max_joint_move_rad", "max_lift_m", "fd_step_rad"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"RepairConfig.{name} must be finite and >= 0, got {value}")
        if not self.fd_step_rad > 0.0 or not self.step_rad > 0.0:
            raise ValueError(f"RepairConfig.step_rad and fd_step_rad must be > 0, got {self.step_rad}, {self.fd_step_rad}")
        if self.max_steps < 1:
            raise ValueError(f"RepairConfig.max_steps must be >= 1, got {self.max_steps}")


class RepairStatus(Enum):
    """What :func:`repair_start` found."""

    VALID = "valid"  # valid as measured: nothing changed
    REPAIRED = "repaired"  # made valid within the bounds
    FAILED = "failed"  # not valid within the bounds (``StartRepair.after`` says why)


@dataclass(frozen=True)
class JointMove:
    """One joint's change [rad] (repaired minus measured)."""

    joint: str
    delta_rad: float


@dataclass(frozen=True)
class StartRepair:
    """A measured posture made a valid start (or why not).

    Attributes:
        status: valid as measured, repaired, or failed.
        posture: the start to plan from (FAILED: the last one tried, not valid).
        measured: the posture as given.
        lift_m: [m] how far the root was lifted.
        joint_moves: the joints changed, largest change first.
        before: the checker's reasons against the measured posture (empty: it was valid).
        after: its reasons against ``posture`` (empty unless FAILED).
        steps: steps taken.
    """

    status: RepairStatus
    posture: Posture
    measured: Posture
    lift_m: float = 0.0
    joint_moves: tuple[JointMove, ...] = ()
    before: tuple[str, ...] = ()
    after: tuple[str, ...] = ()
    steps: int = 0

    @property
    def valid(self) -> bool:
        """``posture`` is a valid start."""
        return self.status is not RepairStatus.FAILED

    @property
    def changed(self) -> bool:
        return self.lift_m > 0.0 or bool(self.joint_moves)

    @property
    def max_joint_move_rad(self) -> float:
        return max((abs(m.delta_rad) for m in self.joint_moves), default=0.0)

    def describe(self) -> str:
        """One line: what was changed and why (empty when valid as measured)."""
        if self.status is RepairStatus.VALID:
            return ""
        changes = []
        if self.lift_m > 0.0:
            changes.append(f"root lifted {self.lift_m * 1000:.1f} mm")
        if self.joint_moves:
            changes.append(", ".join(f"{m.joint} {m.delta_rad * 1000:+.0f} mrad" for m in self.joint_moves))
        was = "; ".join(self.before[:MAX_REASONS]) + (f" (+{len(self.before) - MAX_REASONS} more)" if len(self.before) > MAX_REASONS else "")
        if self.status is RepairStatus.REPAIRED:
            return f"start repaired ({'; '.join(changes) or 'nothing moved'}) from: {was}"
        return (f"start not repairable within {self.steps} steps ({'; '.join(changes) or 'nothing moved'}): "
                f"{'; '.join(self.after)} (measured: {was})")

    def to_dict(self) -> dict[str, Any]:
        return {"status": self.status.value, "lift_m": self.lift_m,
                "joint_moves_rad": {m.joint: m.delta_rad for m in self.joint_moves},
                "before": list(self.before), "after": list(self.after), "steps": self.steps}


def repair_start(posture: Posture, checker: ValidityChecker, *, config: RepairConfig = RepairConfig()) -> StartRepair:
    """Make a measured lying posture a valid start for ``checker`` (see the module docstring).

    Args:
        posture: the measured posture (joint angles, root pose).
        checker: the validity checker of the robot and scene the start is planned in.
        config: margins and bounds.

    Returns:
        the repair: status, the start to plan from, and what changed.
    """
    before = checker.check(posture)
    if before.valid:
        return StartRepair(RepairStatus.VALID, posture, posture)
    robot, idx = checker.robot, checker.index
    q0 = checker.qpos_of(posture)
    q = q0.copy()
    qj = idx.qpos_joints
    q[qj] = np.clip(q[qj], robot.joint_lower, robot.joint_upper)  # a clamp is a change too (reported)
    lo = np.maximum(robot.joint_lower, q[qj] - config.max_joint_move_rad)
    hi = np.minimum(robot.joint_upper, q[qj] + config.max_joint_move_rad)
    geometry = _PairGeometry(checker)
    target_m = checker.contact_tolerance_m - config.margin_m  # penetration allowed after the repair
    pairs: set[tuple[int, int]] = set()
    lift = 0.0
    steps = 0
    report = before
    for steps in range(1, config.max_steps + 1):
        pairs |= {geometry.pair(c.geom1, c.geom2) for c in report.collisions if c.kind == "self"}
        moved = _nudge_apart(geometry, q, sorted(pairs), target_m, lo, hi, config)
        sink = -checker.check_qpos(q).ground_clearance_m - target_m
        lifted = 0.0
        if sink > 0.0 and lift < config.max_lift_m:
            lifted = min(sink + 1e-5, config.max_lift_m - lift)  # a hair more: float rounding
            q[idx.qpos_root[2]] += lifted
            lift += lifted
        report = checker.check_qpos(q)
        if (report.valid and _deepest_self_m(geometry, q, sorted(pairs)) <= target_m
                and -report.ground_clearance_m <= target_m):
            break
        if not moved and not lifted:  # no way on within the bounds
            break
    repaired = posture_from_qpos(robot, idx, q)
    dq = q[qj] - q0[qj]
    order = np.argsort(-np.abs(dq))
    moves = tuple(JointMove(robot.joint_names[i], float(dq[i])) for i in order if abs(dq[i]) > 1e-9)
    status = RepairStatus.REPAIRED if report.valid else RepairStatus.FAILED
    result = StartRepair(status, repaired, posture, lift, moves, tuple(before.reasons()),
                         () if report.valid else tuple(report.reasons()), steps)
    log.debug("%s (%d steps)", result.describe(), steps)
    return result


def _deepest_self_m(geometry: _PairGeometry, q: np.ndarray, pairs: list[tuple[int, int]]) -> float:
    """Deepest penetration of the tracked pairs [m] (negative: all apart)."""
    return max((-d for d in geometry.distances(q, pairs)), default=-math.inf)


def _nudge_apart(geometry: _PairGeometry, q: np.ndarray, pairs: list[tuple[int, int]], target_m: float,
                 lo: np.ndarray, hi: np.ndarray, config: RepairConfig) -> bool:
    """One Gauss-Newton step of the chain joints against the pairs' penetration beyond ``target_m``
    (``q`` changed in place); False when nothing moved (nothing to do, or blocked by the bounds)."""
    if not pairs:
        return False

    def excess(qq: np.ndarray) -> float:
        return float(sum(max(0.0, -d - target_m) for d in geometry.distances(qq, pairs)))

    e0 = excess(q)
    if e0 <= 0.0:
        return False
    qj = geometry.qpos_joints
    joints = sorted({k for p in pairs for k in geometry.chain(p)})
    h = config.fd_step_rad
    grad = np.zeros(len(qj))
    for k in joints:
        up, down = q.copy(), q.copy()
        up[qj[k]] += h
        down[qj[k]] -= h
        grad[k] = (excess(up) - excess(down)) / (2 * h)
    present = q[qj]
    # a joint on its bound cannot move further out: leave it out of the step
    grad[((present >= hi - 1e-12) & (grad < 0)) | ((present <= lo + 1e-12) & (grad > 0))] = 0.0
    norm2 = float(grad @ grad)
    if norm2 == 0.0:
        return False
    dq = -e0 * grad / norm2
    biggest = float(np.max(np.abs(dq)))
    if biggest > config.step_rad:
        dq *= config.step_rad / biggest
    new = np.clip(present + dq, lo, hi)
    if np.allclose(new, present, rtol=0.0, atol=1e-9):
        return False
    q[qj] = new
    return True


class _PairGeometry:
    """Signed distances of geom pairs and the driven joints between two bodies, on the checker's model."""

    def __init__(self, checker: ValidityChecker) -> None:
        self.model = checker.model
        self.data = mujoco.MjData(self.model)
        self.linkage = checker.index.linkage
        self.qpos_joints = checker.index.qpos_joints
        m = self.model
        self._geom_id = {(m.geom(g).name or f"geom{g}"): g for g in range(m.ngeom)}  # the checker's names
        driven = {int(a): k for k, a in enumerate(self.qpos_joints)}  # qpos address -> robot joint index
        self._body_joints = {
            b: [driven[int(m.jnt_qposadr[j])] for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b])
                if int(m.jnt_qposadr[j]) in driven]
            for b in range(m.nbody)}
        self._chains: dict[tuple[int, int], tuple[int, ...]] = {}

    def pair(self, name1: str, name2: str) -> tuple[int, int]:
        g1, g2 = self._geom_id[name1], self._geom_id[name2]
        return (g1, g2) if g1 < g2 else (g2, g1)

    def chain(self, pair: tuple[int, int]) -> tuple[int, ...]:
        """Robot joint indices of the kinematic chain between the pair's two bodies."""
        if pair not in self._chains:
            m = self.model

            def path(b: int) -> list[int]:
                out = [b]
                while b != 0:
                    b = int(m.body_parentid[b])
                    out.append(b)
                return out

            p1, p2 = path(int(m.geom_bodyid[pair[0]])), path(int(m.geom_bodyid[pair[1]]))
            common = next(b for b in p1 if b in p2)
            bodies = p1[:p1.index(common)] + p2[:p2.index(common)]
            self._chains[pair] = tuple(k for b in bodies for k in self._body_joints[b])
        return self._chains[pair]

    def distances(self, q: np.ndarray, pairs: list[tuple[int, int]]) -> list[float]:
        """Signed distance of each pair at ``q`` [m] (negative: penetration)."""
        m, d = self.model, self.data
        d.qpos[:] = q
        if self.linkage is not None:
            close_loops(m, d, self.linkage)
        else:
            mujoco.mj_kinematics(m, d)
        return [float(mujoco.mj_geomDistance(m, d, g1, g2, DISTANCE_CAP_M, None)) for g1, g2 in pairs]
