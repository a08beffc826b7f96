"""Closed linkages: the passive joints a robot's constraints move, solved from its driven joints.

A four-bar knee, a coupled neck, a tendon-driven waist: the servos drive some joints (the servo
map's), the model's equality constraints (connect, weld, joint coupling, tendon coupling) move
the rest (``robot.toml`` ``passive``). Simulation enforces the constraints itself; kinematics
does not, so wherever a posture becomes a qpos (validity checks, the start of a play), the
passive joints are solved here: Gauss-Newton on the constraints' residuals over the passive
joints, with a finite-difference Jacobian (a robot has a handful of passive joints).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

__all__ = ["Linkage", "linkage_of", "close_loops", "constraint_residual", "LOOP_TOLERANCE_M"]

LOOP_TOLERANCE_M = 1e-6  # residual [m or rad] at which a loop is closed
_MAX_ITERATIONS = 20
_FD_STEP_RAD = 1e-6


@dataclass(frozen=True)
class Linkage:
    """A model's equality constraints and the passive joints they move.

    Attributes:
        equalities: ids of the active equality constraints.
        passive_qpos: qpos addresses of the passive hinges, shape (p,).
        passive_range: their ranges [rad], shape (p, 2).
    """

    equalities: tuple[int, ...]
    passive_qpos: np.ndarray
    passive_range: np.ndarray

    @property
    def closes_anything(self) -> bool:
        return bool(self.equalities) and len(self.passive_qpos) > 0


def linkage_of(m: mujoco.MjModel, passive_joints: tuple[str, ...]) -> Linkage:
    """The linkage of a model whose ``passive_joints`` (names) its constraints move."""
    ids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in passive_joints]
    ids = [j for j in ids if j >= 0]
    eqs = tuple(e for e in range(m.neq) if m.eq_active0[e])
    qadr = np.array([m.jnt_qposadr[j] for j in ids], dtype=int)
    rng = np.array([m.jnt_range[j] if m.jnt_limited[j] else (-np.pi, np.pi) for j in ids], dtype=float).reshape(-1, 2)
    return Linkage(eqs, qadr, rng)


def _poly(coef: np.ndarray, x: float) -> float:
    return float(coef[0] + coef[1] * x + coef[2] * x**2 + coef[3] * x**3 + coef[4] * x**4)


def constraint_residual(m: mujoco.MjModel, d: mujoco.MjData, equalities: tuple[int, ...]) -> np.ndarray:
    """How far the equality constraints are from holding at ``d``'s kinematics (computed here)."""
    mujoco.mj_kinematics(m, d)
    if m.ntendon:
        mujoco.mj_comPos(m, d)
        mujoco.mj_tendon(m, d)
    out: list[float] = []
    for e in equalities:
        kind, a, b, data = int(m.eq_type[e]), int(m.eq_obj1id[e]), int(m.eq_obj2id[e]), m.eq_data[e]
        if kind in (mujoco.mjtEq.mjEQ_CONNECT, mujoco.mjtEq.mjEQ_WELD):
            if int(m.eq_objtype[e]) == mujoco.mjtObj.mjOBJ_SITE:
                a, b = int(m.site_bodyid[a]), int(m.site_bodyid[b])
            weld = kind == mujoco.mjtEq.mjEQ_WELD
            # MuJoCo's anchors: connect data[0:3] on body1, [3:6] on body2; weld the other way round
            a1, a2 = (data[3:6], data[0:3]) if weld else (data[0:3], data[3:6])
            p1 = d.xpos[a] + d.xmat[a].reshape(3, 3) @ a1
            p2 = d.xpos[b] + d.xmat[b].reshape(3, 3) @ a2
            out.extend(p1 - p2)
            if weld:  # orientation: the vector part of q1^-1 q2 relpose, times the torque scale
                inv, q = np.zeros(4), np.zeros(4)
                mujoco.mju_negQuat(inv, d.xquat[a])
                mujoco.mju_mulQuat(q, d.xquat[b], data[6:10].copy())
                err = np.zeros(4)
                mujoco.mju_mulQuat(err, inv, q)
                out.extend(-err[1:] * data[10])  # MuJoCo's sign
        elif kind == mujoco.mjtEq.mjEQ_JOINT:
            q1 = d.qpos[m.jnt_qposadr[a]] - m.qpos0[m.jnt_qposadr[a]]
            q2 = d.qpos[m.jnt_qposadr[b]] - m.qpos0[m.jnt_qposadr[b]] if b >= 0 else 0.0
            out.append(q1 - _poly(data[0:5], q2))
        elif kind == mujoco.mjtEq.mjEQ_TENDON:
            l1 = d.ten_length[a] - m.tendon_length0[a]
            l2 = d.ten_length[b] - m.tendon_length0[b] if b >= 0 else 0.0
            out.append(l1 - _poly(data[0:5], l2))
    return np.asarray(out, dtype=float)


def close_loops(m: mujoco.MjModel, d: mujoco.MjData, linkage: Linkage) -> float:
    """Set the passive joints in ``d.qpos`` so the constraints hold (least squares, within their
    ranges); returns the residual left [m or rad]. ``d``'s kinematics are left computed."""
    if not linkage.closes_anything:
        return 0.0
    adr = linkage.passive_qpos
    lo, hi = linkage.passive_range[:, 0], linkage.passive_range[:, 1]
    r = constraint_residual(m, d, linkage.equalities)
    for _ in range(_MAX_ITERATIONS):
        if not len(r) or np.abs(r).max() < LOOP_TOLERANCE_M:
            break
        base = d.qpos[adr].copy()
        J = np.zeros((len(r), len(adr)))
        for k in range(len(adr)):
            d.qpos[adr[k]] = base[k] + _FD_STEP_RAD
            J[:, k] = (constraint_residual(m, d, linkage.equalities) - r) / _FD_STEP_RAD
            d.qpos[adr[k]] = base[k]
        step = np.linalg.lstsq(J, -r, rcond=None)[0]
        d.qpos[adr] = np.clip(base + step, lo, hi)
        r = constraint_residual(m, d, linkage.equalities)
    return float(np.abs(r).max()) if len(r) else 0.0
