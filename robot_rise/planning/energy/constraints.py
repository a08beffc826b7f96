"""Constrained steps (paper 004 section 6.1, Algorithm 2): joint limits, positional constraints, ground contacts.

A step dq in the scaled tangent chart is projected onto the null space of the linearised
constraints K dq = C (eq. 9-11): joint-limit rows for the joints it would carry past a bound
(eq. 13), positional rows for the points kept in place (eq. 12).

Ground contacts as automatic positional constraints (ours): a lying robot rests on the floor, and
with d = 3 the internal term (exponent d) can outweigh the ground term (exponent 2), so its
gradient pushes a resting foot or the torso through the floor and every attempt of Algorithm 1
is rejected. Then the attempts are repeated with the touching points (within
GROUND_CONTACT_ZONE_M) that the step would lower held on the plane, in the active-set manner of
the joint-limit rows of eq. (13). Section 8 of the paper assumes such "contact invariant" segments.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from robot_rise.constants import GROUND_CONTACT_ZONE_M
from robot_rise.planning.energy.config import EnergyConfig
from robot_rise.planning.energy.repulsive import RepulsiveEnergy
from robot_rise.validity import ValidityChecker

__all__ = ["PositionalConstraint", "StepConstraints", "project_constraints", "with_ground_contacts"]


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


class StepConstraints:
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


def project_constraints(dq: np.ndarray, K: np.ndarray, C: np.ndarray, g_hat: np.ndarray, p: EnergyConfig) -> np.ndarray:
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


def with_ground_contacts(
    energy: RepulsiveEnergy, qh: np.ndarray, dy: np.ndarray, K: np.ndarray, C: np.ndarray, g_hat: np.ndarray, scale: np.ndarray, p: EnergyConfig
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
        step = project_constraints(dy, KK, CC, g_hat, p)
    if not rows:
        return K, C
    return np.vstack([K, np.array(rows)]), np.concatenate([C, np.array(targets)])
