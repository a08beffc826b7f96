"""The second stage's motion written out densely (the frames' polyline or their B-spline), so that the shared timing sees its shape."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from robot_rise.constants import ENERGY_VERIFY_RESOLUTION_M, OUTPUT_SPACING_RAD, ROOT_TRANSLATION_SCALE_M
from robot_rise.planning.energy.deadline import deadline_passed
from robot_rise.planning.energy.tangent import resample_path, tangent_difference, tangent_scale, tangent_step
from robot_rise.planning.motion_validator import MotionValidator
from robot_rise.planning.problem import PostureSequence
from robot_rise.planning.timing import integrated_squared_jerk, time_parameterize
from robot_rise.posture import posture_from_qpos
from robot_rise.validity import ValidityChecker

__all__ = ["timed_roughness", "dense_output"]


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


def timed_roughness(checker: ValidityChecker, path: np.ndarray) -> float:
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
    root_translation_scale_m: float = ROOT_TRANSLATION_SCALE_M,
    validator: MotionValidator | None = None,
    deadline: float | None = None,
    stats: dict[str, Any] | None = None,
) -> np.ndarray:
    """The second stage's motion written out densely, so that the shared timing sees its shape.

    The shared timing (timing.py) caps the speed at each knot by the change of direction there;
    frames ``frame_spacing_rad`` apart, densified linearly by the timing or the smoother's curve
    into 2-3 steps each, make a bend every few knots and the speed oscillates (issue 7:
    arm under the back, J x D^5 11x that of the same frames written 5x denser; measured when the
    timing's path parameter was the waypoint index, so uneven spacing bent it too: since
    2026-12-03 it is the path length, and only the frames' own bends remain). Two dense
    versions of the frames, both ``spacing_rad`` apart or closer (scaled tangent norm):

    - the frames' polyline resampled (``resample_path``): legal, as the frames' segments are;
    - the uniform cubic B-spline of the frames (C2: no bend at the frames), kept only if every
      sample and segment is legal at ``resolution_m``.

    The one whose shared timing has the lower jerk at a common duration (J x D^5) is returned.

    Args:
        path: a legal motion, qpos rows, shape (K, nq).
        validator: a segment checker of the checker's robot to reuse (built otherwise); it checks
            at ``resolution_m``.
        deadline: ``time.monotonic()`` value; once passed (while the curve is checked or before
            the two are timed), the polyline is returned.
        stats: filled with ``output`` ("polyline" or "bspline"), ``output_frames`` and
            ``stopped_on_budget`` (True when the deadline left the curve unchecked or untimed).

    Returns:
        qpos rows, shape (K', nq), K' >= K, same first and last row.
    """
    validator = MotionValidator.for_checker(checker, resolution_m) if validator is None else validator.with_resolution(resolution_m)
    scale = tangent_scale(checker, root_translation_scale_m)
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
            if deadline_passed(deadline):
                legal, stopped = False, True
                break
            if (k < len(spline) - 1 and not checker.is_valid_qpos(spline[k])) or not validator.qpos_segment_valid(spline[k - 1], spline[k]):
                legal = False
                break
        if legal and deadline_passed(deadline):
            legal, stopped = False, True
        if legal and timed_roughness(checker, spline) < timed_roughness(checker, poly):
            out, kind = spline, "bspline"
    if stats is not None:
        stats.update(output=kind, output_frames=len(out), stopped_on_budget=stopped)
    return out
