"""Measures of a timed path in the energy-planner benchmark (issue 7): jerk three ways, the root's motion.

The integrated squared jerk itself is the timing's (:func:`robot_rise.planning.timing.integrated_squared_jerk`);
these make paths of different durations and amplitudes comparable.
"""

from __future__ import annotations

import math

import numpy as np

from robot_rise.planning.timing import integrated_squared_jerk

__all__ = ["dimensionless_jerk", "common_duration_jerk", "root_motion"]


def dimensionless_jerk(t: np.ndarray, q: np.ndarray) -> float:
    """Integrated squared jerk times D^5 / A^2 (Hogan & Sternad 2009): duration D [s], joint-space path length A [rad].

    Scale-free: the same path shape played slower or scaled in amplitude gives the same value, so
    long slow paths and short quick ones compare on shape and timing profile alone.
    """
    if len(t) < 4:
        return 0.0
    amp = float(np.sum(np.linalg.norm(np.diff(q, axis=0), axis=1)))
    dur = float(t[-1] - t[0])
    return integrated_squared_jerk(t, q) * dur**5 / max(amp, 1e-9) ** 2


def common_duration_jerk(jerk: float, duration_s: float, reference_s: float) -> float:
    """Integrated squared jerk of the same motion played uniformly slower or faster, in ``reference_s`` [rad^2/s^5].

    Playing q(t) as q(t D / D_ref) multiplies the third derivative by (D / D_ref)^3 and the
    integration interval by D_ref / D, so the integral scales exactly by (D / D_ref)^5. The raw
    integral therefore ranks a path partly by how slowly it is timed (a path timed twice as long
    has 1/32 of the jerk); at a common duration the paths compare on shape and timing profile,
    while amplitude (a longer path needs more jerk in the same time) still counts, unlike the
    dimensionless jerk.
    """
    if not (duration_s > 0 and reference_s > 0):
        return math.nan
    return jerk * (duration_s / reference_s) ** 5


def root_motion(root: np.ndarray | None) -> tuple[float, float]:
    """Travel [m] of the root position and total rotation [rad] of its orientation along rows (T, 7); NaN without rows."""
    if root is None or len(root) < 2:
        return math.nan, math.nan
    from robot_rise.planning.space import quat_angle

    travel = float(np.sum(np.linalg.norm(np.diff(root[:, :3], axis=0), axis=1)))
    rot = float(np.sum(2.0 * quat_angle(root[:-1, 3:7], root[1:, 3:7])))
    return travel, rot
