"""The second stage: a legal first-stage motion projected onto the constraint manifold of paper 004 section 6.2.

Frames kept close to the first-stage motion, a Laplacian smoothness term on the trajectory, the
linear-momentum term of eq. (18) (weight 0 by default, as in the paper's eq. 20), joint limits and
positional constraints as hard constraints, and the validity checker as the judge of every frame
and segment (no new penetration). (Named ``projection`` so that the package face can export the
function ``second_stage`` without shadowing a submodule of that name.)
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from robot_rise.constants import ENERGY_VERIFY_RESOLUTION_M, ROOT_TRANSLATION_SCALE_M
from robot_rise.planning.energy.config import EnergyConfig, SecondStageConfig
from robot_rise.planning.energy.constraints import PositionalConstraint, StepConstraints, project_constraints
from robot_rise.planning.energy.deadline import deadline_passed
from robot_rise.planning.energy.tangent import resample_path, tangent_difference, tangent_scale, tangent_step
from robot_rise.planning.motion_validator import MotionValidator
from robot_rise.validity import ValidityChecker

__all__ = ["second_stage", "trajectory_laplacian_energy"]


def trajectory_laplacian_energy(checker: ValidityChecker, path: np.ndarray, scale: np.ndarray | None = None) -> float:
    """Sum over interior frames of 1/2 |y_(t-1) - 2 y_t + y_(t+1)|^2, y the scaled tangent chart at the first frame [rad^2]."""
    sc = scale if scale is not None else tangent_scale(checker)
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
    params: SecondStageConfig = SecondStageConfig(),
    constraints: tuple[PositionalConstraint, ...] = (),
    resolution_m: float = ENERGY_VERIFY_RESOLUTION_M,
    root_translation_scale_m: float = ROOT_TRANSLATION_SCALE_M,
    validator: MotionValidator | None = None,
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
        validator: a segment checker of the checker's robot to reuse (built otherwise); it checks
            at ``resolution_m``.
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
    scale = tangent_scale(checker, root_translation_scale_m)
    ep = EnergyConfig()  # eq. (10)-(11)'s damping and energy step (the defaults)
    validator = MotionValidator.for_checker(checker, resolution_m) if validator is None else validator.with_resolution(resolution_m)
    q = resample_path(checker, np.asarray(path, dtype=float), params.frame_spacing_rad, scale)
    n, nv = len(q), int(m.nv)
    st = stats if stats is not None else {}
    st.update(frames=n, iterations=0, held=0, stopped_on_budget=False, laplacian_before=trajectory_laplacian_energy(checker, q, scale))
    if n < 3 or params.iterations == 0:
        st["laplacian_after"] = st["laplacian_before"]
        return q
    q_ref = q[0].copy()
    cons = StepConstraints(checker, constraints, scale)
    com = _CoM(checker, scale, q_ref)
    qj = checker.index.qpos_joints
    lo, hi = checker.robot.joint_lower, checker.robot.joint_upper
    D = _second_difference(n)
    inner = slice(1, n - 1)
    DtD = (D.T @ D).tocsr()
    A_lap = sparse.kron(DtD[inner, inner], sparse.identity(nv), format="csr")

    def seg_ok(a: np.ndarray, b: np.ndarray) -> bool:
        return validator.qpos_segment_valid(a, b)

    for it in range(params.iterations):
        if deadline_passed(deadline):  # every finished iteration's motion is legal: stop between two
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
                step[t] = project_constraints(step[t], K, C, np.zeros(nv), ep)
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
