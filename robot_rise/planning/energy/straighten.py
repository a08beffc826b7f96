"""Straightened limbs (ours): the root and each linkage of paper 004 Fig. 8 put on its straight motion where legal.

Section 5.1's "unnecessary expansion": the energy moves parts the problem does not need to move,
and brings them back; each part's excursion is undone when the result stays legal.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from robot_rise.constants import ENERGY_VERIFY_RESOLUTION_M, ROOT_TRANSLATION_SCALE_M
from robot_rise.planning.energy.deadline import deadline_passed
from robot_rise.planning.energy.gli import LINKAGE_ORDER
from robot_rise.planning.energy.tangent import tangent_difference, tangent_scale, tangent_step
from robot_rise.planning.motion_validator import MotionValidator
from robot_rise.validity import ValidityChecker

__all__ = ["straighten_limbs"]


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
    root_translation_scale_m: float = ROOT_TRANSLATION_SCALE_M,
    validator: MotionValidator | None = None,
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
        validator: a segment checker of the checker's robot to reuse (built otherwise); it checks
            at ``resolution_m``.
        deadline: ``time.monotonic()`` value; once passed, the remaining parts are left as they are.
        stats: filled with ``straightened``: the names of the parts made straight, and
            ``stopped_on_budget`` (True when the deadline left parts untried).

    Returns:
        qpos rows, shape (K, nq).
    """
    m = checker.model
    validator = MotionValidator.for_checker(checker, resolution_m) if validator is None else validator.with_resolution(resolution_m)
    scale = tangent_scale(checker, root_translation_scale_m)
    q = np.array(path, dtype=float)
    done: list[str] = []
    stopped = False
    if len(q) > 2:
        qj = checker.index.qpos_joints
        lo, hi = checker.robot.joint_lower, checker.robot.joint_upper
        for name, dofs in _limb_dofs(checker):
            if deadline_passed(deadline):
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
                validator.qpos_segment_valid(a, b) for a, b in zip(cand[:-1], cand[1:])
            ):
                q = cand
                done.append(name)
    if stats is not None:
        stats["straightened"] = done
        stats["stopped_on_budget"] = stopped
    return q
