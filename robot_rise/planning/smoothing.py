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

Verification and local repair: the curve is sampled densely and every motion between samples
is checked with the validity checker at the verification resolution. Where a piece of the curve
cuts a corner into collision, two repairs, in this order:

a. Put back waypoints the shortcut removed (ours, issue 7): for every edge among the piece's
   control points that replaced original waypoints, the removed waypoint in the middle (by index)
   is re-inserted unless it is a detour (``restore_max_detour``), and the curve is rebuilt. Every
   edge of the control polygon stays either a verified shortcut or an original edge, so the
   polygon stays legal; repeated, this converges to the curve of the planner's own waypoints
   there. Why: a planner whose path is already short and smooth (the energy planner) loses it to
   the shortcut, which pulls it taut against a contact; the taut polygon's curve then cuts the
   contact, and before this repair every such point became a hard corner at which the
   time-optimal timing stops. Bisection, and no detours, rather than re-inserting all removed
   waypoints at once: a random planner's wandering stretch does not come back.
b. Hard corners, only where nothing is left to put back: the control points of the offending
   piece are tripled. A piece whose control points are all tripled IS the straight polyline
   between them, which is legal, so repeated tripling converges to the legal polyline locally and
   leaves the rest smooth.

If a and b together do not converge within ``max_rounds``, the curve is rebuilt with b alone
(the smoother before issue 7), then the polygon is the last resort.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, replace

import numpy as np

from robot_rise.constants import VERIFY_RESOLUTION_M
from robot_rise.planning.motion_validator import MotionValidator
from robot_rise.planning.problem import PostureSequence
from robot_rise.planning.space import PostureSpace
from robot_rise.planning.timing import integrated_squared_jerk, time_parameterize
from robot_rise.validity import ValidityChecker

__all__ = ["QUICK_SMOOTHING", "SmoothingConfig", "SmoothingReport", "smooth_path", "smooth_path_report", "shortcut", "shortcut_indices", "bspline_samples", "tripling_only"]

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
        max_rounds: repair rounds (put back or triple) before falling back to the polyline.
        restore_waypoints: repair a, putting back removed waypoints before tripling (False, with
            max_rounds=8: the smoother before issue 7's fix, kept for the ablation and the tests).
        restore_max_detour: largest relative lengthening of an edge by a put-back waypoint.
        try_without_shortcut: candidate d of smooth_path (the planner's waypoints, not shortcut).
        compare_hard_corners: with ``restore_waypoints``, also smooth with hard corners alone and
            keep the smoother-timed curve (see smooth_path).
    """

    shortcut_attempts: int = 150
    shortcut_budget_s: float | None = None
    sample_spacing_m: float = 0.02
    resolution_m: float = VERIFY_RESOLUTION_M
    # 8 tripling rounds suffice when only tripling (each round spreads a corner by one piece); the
    # bisection of repair a adds up to log2(K) rounds for a K-waypoint stretch (K ~ 100 frames of
    # the energy planner's second stage: 7), hence 8 + 8.
    max_rounds: int = 2 * 8
    restore_waypoints: bool = True
    # Repair a puts back a removed waypoint only if routing the edge through it lengthens the edge
    # by at most this fraction (robot-point travel). The middle of a smooth arc of up to ~110 deg
    # passes (1/cos(theta/4) - 1 <= 0.15 in a Euclidean metric); a random planner's detour, which
    # the shortcut rightly removed, does not: first measured without the limit, RRT-blossom on
    # crossed arms (seed 0) came back through its detour, 1.87 s -> 3.46 s and 9x the
    # dimensionless jerk. Such an edge gets repair b instead.
    restore_max_detour: float = 0.15
    # Also smooth the planner's own waypoints without shortcutting and keep that curve if its
    # timing is smoother (lower J x D^5) and no slower. The shortcut is there for random planners'
    # wander; a planner whose path is already short and smooth (the energy planner's second
    # stage) loses more to it than repair a gives back (issue 7: lying60 median dimensionless jerk
    # 8.3e5 through the shortcut, 2.3e4 without).
    try_without_shortcut: bool = True
    compare_hard_corners: bool = True


QUICK_SMOOTHING = SmoothingConfig(try_without_shortcut=False, compare_hard_corners=False)
"""One curve (shortcut, then repairs a and b), no alternatives compared by their jerk: about a
third of the default's work (two thirds of a live get-up's planning time went to smoothing three
curves: profile of 2026-12-03), for what a robot lying on the floor waits on (``rise(composed=True)``)."""


@dataclass(frozen=True)
class SmoothingReport:
    """What the smoother did (for benchmarks and tests).

    Attributes:
        n_input: waypoints given.
        n_after_shortcut: control points after shortcutting.
        n_restored: removed waypoints put back (repair a).
        n_control: control points of the final curve.
        n_hard_corners: control points tripled (repair b), i.e. points where the curve stops bending
            smoothly and the timing slows to rest; ends excluded.
        rounds: repair rounds used.
        fell_back: True when the curve stayed illegal and the polyline was returned.
    """

    n_input: int
    n_after_shortcut: int
    n_restored: int
    n_control: int
    n_hard_corners: int
    rounds: int
    fell_back: bool


def _states(seq: PostureSequence) -> np.ndarray:
    return np.concatenate([seq.root_pos, seq.root_quat_wxyz, seq.joints], axis=1)


def shortcut(states: np.ndarray, validator: MotionValidator, rng: np.random.Generator, attempts: int, deadline: float) -> np.ndarray:
    """Random shortcutting: replace waypoints i+1..j-1 by the straight motion i -> j when legal.

    Args:
        states: path, shape (K, 7 + n); assumed legal.
    Returns:
        a legal path with the same ends, shape (K', 7 + n), K' <= K.
    """
    return states[shortcut_indices(states, validator, rng, attempts, deadline)]


def shortcut_indices(states: np.ndarray, validator: MotionValidator, rng: np.random.Generator, attempts: int, deadline: float) -> np.ndarray:
    """As :func:`shortcut`, returning which waypoints it keeps: increasing indices, shape (K',),
    first 0 and last K - 1 (same random draws, so the same result for a seed)."""
    path = list(range(len(states)))
    for _ in range(attempts):
        if len(path) < 3 or time.monotonic() > deadline:
            break
        i, j = sorted(rng.choice(len(path), size=2, replace=False))
        if j - i < 2:
            continue
        if validator.segment_valid(states[path[i]], states[path[j]], check_end=False):
            path = path[: i + 1] + path[j:]
    return np.array(path, dtype=int)


def bspline_points(ctrl: np.ndarray, mult: np.ndarray, space: PostureSpace, spacing_m: float, validator: MotionValidator) -> tuple[np.ndarray, np.ndarray]:
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
    return bspline_points(ctrl, mult, space, spacing_m, validator)[0]


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
        If smoothing cannot be made legal it returns the (legal) control polygon, densified.

    With ``config.restore_waypoints`` (default) the path is smoothed twice, with repair a and with
    hard corners alone (``tripling_only``), and the curve whose default servo-limited timing has
    the lower jerk at a common duration is returned. Why: repair a removes the stops at hard
    corners, but a put-back waypoint can leave a tight bend passed at speed, which measured
    rougher than a stop on some paths (issue 7, with repair a alone: RRT-blossom 6 of lying60's 60
    problems more than 2x the dimensionless jerk; energy planner, arm under the back, 1 of 5, 400x).
    With ``config.try_without_shortcut`` (default) the curve of the planner's own waypoints (no
    shortcut) is a further candidate, kept only if it times smoother and no slower.
    """
    space = PostureSpace.for_robot(checker.robot)
    if tuple(seq.joint_names) != space.joint_names:
        raise ValueError("smooth_path: the sequence's joint order differs from the checker's robot")
    states = _states(seq)
    out, n_restored = _smooth_through(seq, states, checker, space, config, seed, through)
    timed_out: tuple[float, float] | None = None  # (J x D^5, D) of ``out``, computed once when needed
    if config.restore_waypoints and config.compare_hard_corners and n_restored:
        alt = _smooth_through(seq, states, checker, space, tripling_only(config), seed, through)[0]
        timed_out, timed_alt = _timed(out, checker), _timed(alt, checker)
        if timed_alt[0] < timed_out[0]:
            log.debug("hard corners alone time smoother than with waypoints put back: kept")
            out, timed_out = alt, timed_alt
    if config.try_without_shortcut and config.shortcut_attempts > 0 and len(states) > 2:
        whole = _smooth_through(seq, states, checker, space, replace(config, shortcut_attempts=0), seed, through)[0]
        (j_out, d_out) = timed_out if timed_out is not None else _timed(out, checker)
        j_whole, d_whole = _timed(whole, checker)
        if j_whole < j_out and d_whole <= d_out:
            log.debug("the curve of the planner's own waypoints times smoother and no slower: kept")
            out = whole
    return out


def _smooth_through(
    seq: PostureSequence, states: np.ndarray, checker: ValidityChecker, space: PostureSpace, config: SmoothingConfig, seed: int, through: tuple[int, ...]
) -> tuple[PostureSequence, int]:
    """Pieces between key postures smoothed separately (see smooth_path); also the number of
    waypoints put back (repair a) over all pieces."""
    cuts = sorted({int(i) for i in through if 0 < int(i) < len(states) - 1})
    bounds = [0, *cuts, len(states) - 1]
    done = [_smooth_repaired(seq, states[i : j + 1], checker, space, config, seed) for i, j in zip(bounds[:-1], bounds[1:])]
    if len(done) == 1:
        return done[0][0], done[0][1].n_restored
    joined = np.concatenate([_states(p) if k == 0 else _states(p)[1:] for k, (p, _) in enumerate(done)])
    return _sequence(seq, joined), sum(r.n_restored for _, r in done)


def timed_jerk(seq: PostureSequence, checker: ValidityChecker) -> float:
    """Integrated squared jerk x D^5 of the path's default servo-limited timing [rad^2]: ranks two
    curves of one path by their jerk at a common duration (BENCHMARKS, issue 7)."""
    return _timed(seq, checker)[0]


def _timed(seq: PostureSequence, checker: ValidityChecker) -> tuple[float, float]:
    """(J x D^5 [rad^2], D [s]) of the path's default servo-limited timing."""
    timed = time_parameterize(seq, checker.robot)
    return integrated_squared_jerk(timed.t, timed.joints) * timed.duration_s**5, timed.duration_s


def smooth_path_report(
    seq: PostureSequence,
    checker: ValidityChecker,
    *,
    config: SmoothingConfig = SmoothingConfig(),
    seed: int = 0,
) -> tuple[PostureSequence, SmoothingReport]:
    """:func:`smooth_path` without key postures, also saying what the smoother did."""
    space = PostureSpace.for_robot(checker.robot)
    if tuple(seq.joint_names) != space.joint_names:
        raise ValueError("smooth_path: the sequence's joint order differs from the checker's robot")
    return _smooth_repaired(seq, _states(seq), checker, space, config, seed)


def _smooth_repaired(
    seq: PostureSequence, states: np.ndarray, checker: ValidityChecker, space: PostureSpace, config: SmoothingConfig, seed: int
) -> tuple[PostureSequence, SmoothingReport]:
    """Repairs a and b; if they do not converge within the rounds, tripling alone (the smoother
    before issue 7, ``max_rounds`` = 8), which converges where it did before: mixing the two
    repairs can need more rounds (RRT-blossom, lying60 left/5: 16 rounds, then the polyline)."""
    out = _smooth_states(seq, states, checker, space, config, seed)
    if out[1].fell_back and config.restore_waypoints:
        log.debug("repairs a + b did not converge; tripling only")
        out = _smooth_states(seq, states, checker, space, tripling_only(config), seed)
    return out


_TRIPLING_ROUNDS = 8  # the smoother's rounds before issue 7 (tripling only)


def tripling_only(config: SmoothingConfig) -> SmoothingConfig:
    """The same knobs with repair b alone: the smoother as it was before issue 7's repair a."""
    return replace(config, restore_waypoints=False, max_rounds=_TRIPLING_ROUNDS, try_without_shortcut=False)


def _smooth_states(
    seq: PostureSequence, states: np.ndarray, checker: ValidityChecker, space: PostureSpace, config: SmoothingConfig, seed: int
) -> tuple[PostureSequence, SmoothingReport]:
    """Shortcut, then curve with repairs a and b (module docstring); states shape (K, 7 + n)."""
    validator = MotionValidator(checker, space, config.resolution_m)
    t0 = time.monotonic()
    rng = np.random.default_rng(seed)
    deadline = float("inf") if config.shortcut_budget_s is None else t0 + config.shortcut_budget_s
    keep = shortcut_indices(states, validator, rng, config.shortcut_attempts, deadline)
    n_short = len(keep)
    tripled = np.zeros(len(states), dtype=bool)  # by original index
    tripled[0] = tripled[-1] = True  # the clamped ends
    n_restored = 0
    for rnd in range(config.max_rounds + 1):
        ctrl = states[keep]
        mult = np.where(tripled[keep], 3, 1)
        samples, owner = bspline_points(ctrl, mult, space, config.sample_spacing_m, validator)
        bad = _bad_intervals(samples, validator)
        if not bad.size:
            report = SmoothingReport(len(states), n_short, n_restored, len(keep), int(np.sum(tripled[keep][1:-1])), rnd, False)
            log.debug("smoothed %s, %d samples, %.3f s", report, len(samples), time.monotonic() - t0)
            return _sequence(seq, samples), report
        if rnd == config.max_rounds:
            break
        expanded: list[int] = []
        for i, m in enumerate(mult):
            expanded += [i] * int(m)
        insert: set[int] = set()
        corners: set[int] = set()
        for piece in sorted({int(owner[k]) for k in bad}):
            cps = sorted(set(expanded[piece : piece + 4]))  # control-point indices of the piece
            mids = []
            if config.restore_waypoints:
                for a, b in zip(cps[:-1], cps[1:]):
                    lo, hi = int(keep[a]), int(keep[b])
                    m = (lo + hi) // 2
                    if hi - lo > 1 and detour(states[lo], states[m], states[hi], validator) <= config.restore_max_detour:
                        mids.append(m)
            if mids:
                insert.update(mids)
            else:
                corners.update(int(keep[c]) for c in cps)
        tripled[list(corners)] = True
        n_restored += len(insert)
        keep = np.array(sorted(set(keep.tolist()) | insert), dtype=int)
    log.info("smoothing fell back to the polyline (curve still illegal after %d rounds)", config.max_rounds)
    ctrl = states[keep]
    dense = [ctrl[0]]
    for a, b in zip(ctrl[:-1], ctrl[1:]):
        n = max(1, int(np.ceil(validator.travel_bound(a, b) / config.sample_spacing_m)))
        dense.extend(space.interpolate(a, b, np.arange(1, n + 1) / n))
    report = SmoothingReport(len(states), n_short, n_restored, len(keep), len(keep) - 2, config.max_rounds, True)
    return _sequence(seq, np.array(dense)), report


def detour(a: np.ndarray, m: np.ndarray, b: np.ndarray, validator: MotionValidator) -> float:
    """Relative lengthening of a -> b when routed through m (robot-point travel bound), >= 0."""
    direct = validator.travel_bound(a, b)
    return (validator.travel_bound(a, m) + validator.travel_bound(m, b)) / max(direct, 1e-12) - 1.0


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
