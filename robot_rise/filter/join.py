"""Reshaping targets in time: join a planned path to a library motion with a blend, stretch windows of time.

Paper 000 section 4.3 connects the smoothed plan to the database motion at the most similar
frame with blending; dissertation 003 eq. 2.9-2.10's comfort control lowers the speed where
torque exceeds the limit, which for servo targets is stretching their clock.
"""

from __future__ import annotations

import numpy as np

from robot_rise.trajectory import Trajectory

__all__ = ["join_with_blend", "join_with_overlap", "overlap_of", "time_scale"]


def join_with_blend(plan: Trajectory, motion: Trajectory, frame: int, *, blend_s: float = 0.3, max_speed_rad_s: float = 2.0) -> Trajectory:
    """Plan (lying -> connecting posture) followed by the motion from ``frame`` on.

    The plan ends at (or near) the motion's frame ``frame``. The motion's rows from that frame
    are appended, shifted in time so that the transition from the plan's last row to the
    motion's frame takes at least ``blend_s`` and no joint moves faster than
    ``max_speed_rad_s`` across it: the servos' targets interpolate linearly between them, so a
    mismatch at the join becomes a short blend rather than a step (paper 000 section 4.3).

    Returns:
        a trajectory with the plan's start posture and joint order; its ``root`` rows are the
        plan's then the motion's (the library's simulated root) when both have them.
    """
    names = plan.joint_names
    cols = [motion.joint_names.index(j) for j in names]
    mq = motion.q[frame:, cols]
    mt = motion.t[frame:] - motion.t[frame]
    if len(mt) == 0:
        return plan
    gap = max(blend_s, float(np.max(np.abs(plan.q[-1] - mq[0]))) / max_speed_rad_s)
    t = np.concatenate([plan.t, plan.t[-1] + gap + mt])
    q = np.concatenate([plan.q, mq])
    # the planned root, then the library's simulated one: the lean the filter adapts the body to
    root = np.concatenate([plan.root, motion.root[frame:]]) if plan.root is not None and motion.root is not None else None
    return Trajectory(plan.robot, names, t, q, plan.start, dict(plan.report), root)


def join_with_overlap(plan: Trajectory, motion: Trajectory, frame: int, *, overlap_s: float) -> tuple[Trajectory, int]:
    """Plan followed by the motion from ``frame`` on, the motion starting ``overlap_s`` before
    the plan ends, the two cross-faded over that time.

    The plan ends at rest on (or near) the motion's frame ``frame``; :func:`join_with_blend`
    lets it arrive, pauses, and only then starts the motion. Here the motion's first
    ``overlap_s`` runs while the approach is still decelerating into it: over that time each
    target is ``(1 - w) plan(t) + w motion(t)``, ``w`` rising smoothly (smoothstep) from 0 to 1,
    so the targets neither jump nor stop (issue 17: phases that can overlap overlap; paper 000
    section 4.3 connects with blending). The filter proves the result as any other join. The
    overlap is at most half the plan and at most the rest of the motion (:func:`overlap_of`);
    with none left (a plan of one row, the motion's last frame) use :func:`join_with_blend`.

    Returns:
        the trajectory (the plan's start posture and joint order; ``root`` rows the plan's kept
        rows then the library's simulated ones, the cross-faded rows included, when both have
        them) and its join row: the first row of the motion's part, for
        ``dynamics_filter(join_row=...)`` and the report's ``plan_rows``.

    Raises:
        ValueError: nothing to overlap (:func:`overlap_of` is 0).
    """
    overlap = overlap_of(plan, motion, frame, overlap_s)
    if overlap <= 0.0:
        raise ValueError(f"nothing to overlap: a plan of {plan.duration_s:.3f} s, {motion.duration_s - motion.t[frame]:.3f} s of motion after frame {frame}")
    names = plan.joint_names
    cols = [motion.joint_names.index(j) for j in names]
    mq = motion.q[frame:, cols]
    mt = motion.t[frame:] - motion.t[frame]
    begin = plan.duration_s - overlap  # the motion's first row
    keep = int(np.searchsorted(plan.t, begin - 1e-6))  # the plan's rows before it (at least its first: begin >= half the plan)
    t = begin + mt
    inside = mt < overlap
    s = mt[inside] / overlap
    w = (s * s * (3.0 - 2.0 * s))[:, None]
    approach = np.column_stack([np.interp(t[inside], plan.t, plan.q[:, j]) for j in range(len(names))])
    q = np.concatenate([plan.q[:keep], (1.0 - w) * approach + w * mq[inside], mq[~inside]])
    root = np.concatenate([plan.root[:keep], motion.root[frame:]]) if plan.root is not None and motion.root is not None else None
    return Trajectory(plan.robot, names, np.concatenate([plan.t[:keep], t]), q, plan.start, dict(plan.report), root), keep


def overlap_of(plan: Trajectory, motion: Trajectory, frame: int, overlap_s: float) -> float:
    """The overlap :func:`join_with_overlap` uses [s]: ``overlap_s`` cut to half the plan (the
    approach keeps its first half) and to the motion's rest after ``frame`` (the fade ends
    within the motion), never below 0."""
    return max(0.0, min(overlap_s, plan.duration_s / 2.0, float(motion.t[-1] - motion.t[frame])))


def time_scale(tr: Trajectory, windows: list[tuple[float, float]], factor: float) -> Trajectory:
    """Stretch time by ``factor`` inside ``windows`` (trajectory clock, seconds); rows unchanged."""
    if not windows:
        return tr
    t = tr.t
    dt = np.diff(t)
    mid = (t[:-1] + t[1:]) / 2
    scale = np.ones_like(dt)
    for a, b in windows:
        scale[(mid >= a) & (mid <= b)] = factor
    new_t = np.concatenate([[0.0], np.cumsum(dt * scale)])
    return Trajectory(tr.robot, tr.joint_names, new_t, tr.q, tr.start, tr.report, tr.root)
