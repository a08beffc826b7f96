"""The key postures of a legal path: consecutive ones in one safe subspace (paper 004 section 5.2)."""

from __future__ import annotations

from typing import Any

import numpy as np

from robot_rise.constants import ENERGY_VERIFY_RESOLUTION_M, GLI_SAFE_ZONE_THRESHOLD
from robot_rise.planning.energy.deadline import deadline_passed
from robot_rise.planning.energy.gli import GliMatrix, gli_difference
from robot_rise.planning.motion_validator import MotionValidator
from robot_rise.validity import ValidityChecker

__all__ = ["safe_zone_keyframes"]


def safe_zone_keyframes(
    checker: ValidityChecker,
    path: np.ndarray,
    gli: GliMatrix,
    *,
    threshold: float = GLI_SAFE_ZONE_THRESHOLD,
    resolution_m: float = ENERGY_VERIFY_RESOLUTION_M,
    validator: MotionValidator | None = None,
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
        validator: a segment checker of the checker's robot to reuse (built otherwise); it checks
            at ``resolution_m``.
        deadline: ``time.monotonic()`` value; once passed, the postures after the last key posture
            found are all kept (the raw path's legal segments), so the result is legal but longer.
        stats: filled with ``stopped_on_budget`` (True when the deadline ended the reduction).

    Returns:
        the key postures, shape (K', nq), K' <= K, same first and last row.
    """
    validator = MotionValidator.for_checker(checker, resolution_m) if validator is None else validator.with_resolution(resolution_m)
    mats: dict[int, np.ndarray] = {}
    n = len(path)

    def mat(i: int) -> np.ndarray:
        if i not in mats:
            mats[i] = gli(path[i])
        return mats[i]

    def ok(i: int, j: int) -> bool:
        return gli_difference(mat(i), mat(j)) < threshold and validator.qpos_segment_valid(path[i], path[j])

    keep = [0]
    i = 0
    stopped = False
    while i < n - 1:
        if deadline_passed(deadline):
            stopped = True
            keep.extend(range(i + 1, n))
            break
        lo, hi = i + 1, n - 1  # lo: legal (a verified raw segment)
        if ok(i, hi):
            lo = hi
        while lo < hi and not deadline_passed(deadline):
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
