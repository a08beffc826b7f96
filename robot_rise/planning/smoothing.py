"""Smoothing a planned posture sequence (paper 000 section 4.3), re-verified.

Two steps, each keeping the path legal:

1. Shortcutting (ours, before the paper's curve): RRT-blossom paths wander (the paper notes it
   finds "a collision-free path instead of the shortest path"); random shortcuts replace a
   stretch of waypoints by the straight motion between its ends whenever that motion is legal.
   Deterministic for a seed.
2. The paper's curve: a cubic curve with the planned postures as control points. We use the
   uniform cubic B-spline, i.e. a chain of cubic Bezier pieces through the de Boor points, with
   the end postures tripled so that the curve starts and ends exactly on them. Why the B-spline
   rather than one Bezier of high degree or an interpolating spline: it is C2 (continuous
   acceleration, good for servos), each point depends on 4 control points only (a corner cut
   stays local), and it lies in the convex hull of those 4 (no overshoot beyond the planned
   postures, which an interpolating spline does). Root orientation is blended as quaternions
   (hemisphere-aligned, normalised weighted sum; consecutive control orientations differ by
   small angles, where this matches the spherical blend to second order).

Verification and local fallback: the curve is sampled densely and every motion between samples
is checked with the validity checker at the verification resolution. Where the curve cuts a
corner into collision, the control points of the offending piece are tripled: a piece whose
control points are all tripled IS the straight polyline between them, which was legal, so
repeated tripling converges to the legal polyline locally and leaves the rest smooth.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np

from robot_rise.constants import VERIFY_RESOLUTION_M
from robot_rise.planning.motion_validator import MotionValidator
from robot_rise.planning.problem import PostureSequence
from robot_rise.planning.space import PostureSpace
from robot_rise.validity import ValidityChecker

__all__ = ["SmoothingConfig", "smooth_path", "shortcut", "bspline_samples"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SmoothingConfig:
    """Knobs of the smoother.

    Attributes:
        shortcut_attempts: random shortcut trials.
        shortcut_budget_s: optional wall-clock cap on shortcutting [s]. None (default): the
            attempt count alone bounds the work, so the result depends on the seed only (a
            clock cap made it depend on the machine's load).
        sample_spacing_m: robot-point travel between curve samples [m].
        resolution_m: verification resolution [m] (robot-point travel between checks).
        max_rounds: tripling rounds before falling back to the shortcut polyline.
    """

    shortcut_attempts: int = 150
    shortcut_budget_s: float | None = None
    sample_spacing_m: float = 0.02
    resolution_m: float = VERIFY_RESOLUTION_M
    max_rounds: int = 8


def _states(seq: PostureSequence) -> np.ndarray:
    return np.concatenate([seq.root_pos, seq.root_quat_wxyz, seq.joints], axis=1)


def shortcut(states: np.ndarray, validator: MotionValidator, rng: np.random.Generator, attempts: int, deadline: float) -> np.ndarray:
    """Random shortcutting: replace waypoints i+1..j-1 by the straight motion i -> j when legal.

    Args:
        states: path, shape (K, 7 + n); assumed legal.
    Returns:
        a legal path with the same ends, shape (K', 7 + n), K' <= K.
    """
    path = list(states)
    for _ in range(attempts):
        if len(path) < 3 or time.monotonic() > deadline:
            break
        i, j = sorted(rng.choice(len(path), size=2, replace=False))
        if j - i < 2:
            continue
        if validator.segment_valid(path[i], path[j], check_end=False):
            path = path[: i + 1] + path[j:]
    return np.array(path)


def _bspline_points(ctrl: np.ndarray, mult: np.ndarray, space: PostureSpace, spacing_m: float, validator: MotionValidator) -> tuple[np.ndarray, np.ndarray]:
    """Dense samples of the uniform cubic B-spline of control points with multiplicities.

    Returns:
        (samples shape (M, 7 + n), owner shape (M - 1,): for each sample interval, the index of
        the first original control point of its B-spline piece).
    """
    expanded: list[int] = []
    for i, m in enumerate(mult):
        expanded += [i] * int(m)
    pts: list[np.ndarray] = []
    owner: list[int] = []
    for j in range(len(expanded) - 3):
        ids = expanded[j : j + 4]
        c = ctrl[ids]
        if ids[0] == ids[3]:
            continue  # a degenerate piece sits on one control point
        n = max(2, int(np.ceil(validator.travel_bound(c[0], c[3]) / spacing_m)) + 1)
        u = np.linspace(0.0, 1.0, n)
        if pts:
            u = u[1:]
        b = np.stack([(1 - u) ** 3, 3 * u**3 - 6 * u**2 + 4, -3 * u**3 + 3 * u**2 + 3 * u + 1, u**3], axis=1) / 6.0
        x = b @ c
        q = c[:, 3:7].copy()
        q[np.sum(q * q[0], axis=1) < 0] *= -1.0  # one hemisphere
        qx = b @ q
        x[:, 3:7] = qx / np.linalg.norm(qx, axis=1, keepdims=True)
        pts.extend(x)
        owner.extend([j] * len(x))
    samples = np.array(pts)
    return samples, np.array(owner[1:] if len(owner) > 1 else owner)


def bspline_samples(ctrl: np.ndarray, space: PostureSpace, validator: MotionValidator, spacing_m: float = 0.02) -> np.ndarray:
    """Dense samples of the end-clamped uniform cubic B-spline of ``ctrl`` (K, 7 + n)."""
    mult = np.ones(len(ctrl), dtype=int)
    mult[0] = mult[-1] = 3
    return _bspline_points(ctrl, mult, space, spacing_m, validator)[0]


def smooth_path(
    seq: PostureSequence,
    checker: ValidityChecker,
    *,
    config: SmoothingConfig = SmoothingConfig(),
    seed: int = 0,
    through: tuple[int, ...] = (),
) -> PostureSequence:
    """Shortcut and B-spline-smooth a legal posture sequence; the result is legal and dense.

    Args:
        seq: a legal path (e.g. a planner's), K >= 2 waypoints.
        checker: the strict validity checker of the scene.
        config: knobs.
        seed: shortcut randomness.
        through: indices of interior waypoints the result must pass exactly (a key posture):
            the pieces between them are smoothed separately, each clamped at its ends.

    Returns:
        a posture sequence with the same first and last posture, legal at
        ``config.resolution_m``, with waypoints every ~``sample_spacing_m`` of robot travel.
        If smoothing cannot be made legal it returns the (legal) shortcut polyline, densified.
    """
    space = PostureSpace.for_robot(checker.robot)
    if tuple(seq.joint_names) != space.joint_names:
        raise ValueError("smooth_path: the sequence's joint order differs from the checker's robot")
    states = _states(seq)
    cuts = sorted({int(i) for i in through if 0 < int(i) < len(states) - 1})
    if cuts:
        bounds = [0, *cuts, len(states) - 1]
        pieces = [smooth_path(_sequence(seq, states[i : j + 1]), checker, config=config, seed=seed) for i, j in zip(bounds[:-1], bounds[1:])]
        return _sequence(seq, np.concatenate([_states(p) if k == 0 else _states(p)[1:] for k, p in enumerate(pieces)]))
    validator = MotionValidator(checker, space, config.resolution_m)
    t0 = time.monotonic()
    rng = np.random.default_rng(seed)
    deadline = float("inf") if config.shortcut_budget_s is None else t0 + config.shortcut_budget_s
    ctrl = shortcut(states, validator, rng, config.shortcut_attempts, deadline)
    mult = np.ones(len(ctrl), dtype=int)
    mult[0] = mult[-1] = 3
    for rnd in range(config.max_rounds + 1):
        samples, owner = _bspline_points(ctrl, mult, space, config.sample_spacing_m, validator)
        bad = _bad_intervals(samples, validator)
        if not bad.size:
            log.debug("smoothed %d -> %d control points -> %d samples in %d rounds, %.3f s", len(states), len(ctrl), len(samples), rnd, time.monotonic() - t0)
            return _sequence(seq, samples)
        if rnd == config.max_rounds:
            break
        expanded: list[int] = []
        for i, m in enumerate(mult):
            expanded += [i] * int(m)
        for k in bad:
            for cp in expanded[owner[k] : owner[k] + 4]:
                mult[cp] = 3
    log.info("smoothing fell back to the shortcut polyline (curve still illegal after %d rounds)", config.max_rounds)
    dense = [ctrl[0]]
    for a, b in zip(ctrl[:-1], ctrl[1:]):
        n = max(1, int(np.ceil(validator.travel_bound(a, b) / config.sample_spacing_m)))
        dense.extend(space.interpolate(a, b, np.arange(1, n + 1) / n))
    return _sequence(seq, np.array(dense))


def _bad_intervals(samples: np.ndarray, validator: MotionValidator) -> np.ndarray:
    """Indices of sample intervals whose motion is illegal (an illegal sample taints both sides)."""
    bad_pt = np.array([not validator.state_valid(x) for x in samples])
    bad = bad_pt[:-1] | bad_pt[1:]
    for i in np.flatnonzero(~bad):
        bad[i] = not validator.segment_valid(samples[i], samples[i + 1], check_end=False)
    return np.flatnonzero(bad)


def _sequence(like: PostureSequence, states: np.ndarray) -> PostureSequence:
    quat = states[:, 3:7] / np.linalg.norm(states[:, 3:7], axis=1, keepdims=True)
    return PostureSequence(like.robot, like.joint_names, states[:, :3].copy(), quat, states[:, 7:].copy())
