"""From a planning problem to a trajectory file: plan, smooth, time, package.

``plan_trajectory(problem)`` is the one call behind ``robot-rise plan``: RRT-blossom with
loose-to-strict refinement (rrt_blossom/refine.py), shortcut + B-spline smoothing re-verified with the
checker (smoothing.py), servo-limited timing (timing.py), and a ``robot-rise/trajectory@1`` with
the planned root pose per row (``root``) so that anyone can re-check the path kinematically.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from robot_rise.planning.problem import Planner, PlanningProblem, PlanResult, PostureSequence
from robot_rise.planning.rrt_blossom import RRTBlossomPlanner
from robot_rise.planning.space import PostureSpace, quat_angle
from robot_rise.planning.smoothing import SmoothingConfig, smooth_path
from robot_rise.planning.timing import TimedPath, TimingLimits, time_parameterize
from robot_rise.posture import Posture, posture_to_dict
from robot_rise.trajectory import Trajectory
from robot_rise.validity import ValidityChecker

__all__ = ["PlannedTrajectory", "plan_trajectory", "timed_to_trajectory", "path_min_clearance", "path_length"]


@dataclass(frozen=True)
class PlannedTrajectory:
    """Everything ``plan_trajectory`` produced.

    Attributes:
        result: the planner's result (status, raw path, reason, stats).
        smoothed: the smoothed posture sequence (None on failure).
        trajectory: the timed trajectory (None on failure).
        seconds: wall-clock per stage: plan, smooth, time [s].
    """

    result: PlanResult
    smoothed: PostureSequence | None = None
    trajectory: Trajectory | None = None
    seconds: dict[str, float] = field(default_factory=dict)

    @property
    def solved(self) -> bool:
        return self.trajectory is not None


def path_length(seq: PostureSequence, checker: ValidityChecker) -> float:
    """Length of a path in the posture metric of paper 000 eq. (1) (no alignment), summed over edges."""
    space = PostureSpace.for_robot(checker.robot)
    x = np.concatenate([seq.root_pos, seq.root_quat_wxyz, seq.joints], axis=1)
    w = space.orientation_weight
    dq = quat_angle(x[:-1, 3:7], x[1:, 3:7])
    dv = np.diff(x[:, 7:], axis=0)
    return float(np.sum(w * dq + np.sqrt(np.sum(space.joint_weights * dv * dv, axis=1))))


def path_min_clearance(seq: PostureSequence, checker: ValidityChecker, *, stride: int = 1) -> dict[str, float]:
    """Minimum signed clearance per pair class over the waypoints [m] (saturates at the checker's margin)."""
    out = {"ground": np.inf, "self": np.inf, "obstacle": np.inf}
    for q in seq.qpos(checker)[::stride]:
        r = checker.check_qpos(q)
        out["ground"] = min(out["ground"], r.ground_clearance_m)
        out["self"] = min(out["self"], r.self_clearance_m)
        out["obstacle"] = min(out["obstacle"], r.obstacle_clearance_m)
    return {k: float(v) for k, v in out.items()}


def timed_to_trajectory(timed: TimedPath, start: Posture, robot_name: str, report: dict[str, Any] | None = None) -> Trajectory:
    """Package a TimedPath as a Trajectory with ``root`` rows."""
    return Trajectory(robot_name, timed.joint_names, timed.t, timed.joints, start, dict(report or {}), timed.root)


def plan_trajectory(
    problem: PlanningProblem,
    *,
    planner: Planner | None = None,
    smoothing: SmoothingConfig = SmoothingConfig(),
    limits: TimingLimits | None = None,
    smooth: bool = True,
    report_clearance: bool = True,
) -> PlannedTrajectory:
    """Plan, smooth and time a rising path; the report says how (planner stats, timings, limits).

    Args:
        problem: start, goal (connecting posture), optional key, strict checker, budget, seed.
        planner: any Planner (default RRTBlossomPlanner()).
        smoothing: smoother knobs.
        limits: timing limits (default: from the robot's servos).
        smooth: False keeps the planner's polyline (densified by timing only).
        report_clearance: put the path's minimum clearances in the report (a validity check of
            every waypoint: 0.16 s of a live get-up's ~1.5 s of thinking; None in the report without).

    Returns:
        PlannedTrajectory; on planner failure only ``result`` is set, with its reason.
    """
    planner = planner if planner is not None else RRTBlossomPlanner()
    checker = problem.checker
    t0 = time.monotonic()
    result = planner(problem)
    t1 = time.monotonic()
    if not result.solved or result.path is None:
        return PlannedTrajectory(result, seconds={"plan": t1 - t0})
    through: tuple[int, ...] = ()
    if problem.key is not None:  # the key posture is a waypoint of the plan: the smoothed path keeps it exactly
        space = PostureSpace.for_robot(checker.robot)
        x = np.concatenate([result.path.root_pos, result.path.root_quat_wxyz, result.path.joints], axis=1)
        through = (int(np.argmin(space.distance(x, space.state(problem.key)))),)
    smoothed = smooth_path(result.path, checker, config=smoothing, seed=problem.seed, through=through) if smooth else result.path
    t2 = time.monotonic()
    timed = time_parameterize(smoothed, checker.robot, limits=limits)
    t3 = time.monotonic()
    clearance = path_min_clearance(smoothed, checker) if report_clearance else None
    report = {
        "planner": {
            "name": type(planner).__name__,
            "status": result.status.value,
            "seed": problem.seed,
            "budget_s": problem.budget_s,
            "stats": result.stats,
            "waypoints_planned": len(result.path),
            "waypoints_smoothed": len(smoothed),
            "path_length": path_length(smoothed, checker),
            "min_clearance_m": clearance,
            "seconds": {"plan": t1 - t0, "smooth": t2 - t1, "time": t3 - t2},
            "scene": str(checker.scene),
            "goal": posture_to_dict(problem.goal),
            "key": posture_to_dict(problem.key) if problem.key is not None else None,
        },
        "timing": {
            "duration_s": timed.duration_s,
            "max_velocity_ratio": timed.max_velocity_ratio,
            "max_accel_ratio": timed.max_accel_ratio,
        },
    }
    traj = timed_to_trajectory(timed, problem.start, checker.robot.name, report)
    return PlannedTrajectory(result, smoothed, traj, {"plan": t1 - t0, "smooth": t2 - t1, "time": t3 - t2})
