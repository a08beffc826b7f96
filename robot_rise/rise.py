"""The product's main job: from a lying posture to a proven get-up trajectory.

select (paper 000 section 4.1) -> plan (RRT-blossom, section 4.2) -> smooth and time -> join the
library motion -> dynamics filter (section 4.3) -> proof. When a candidate fails (no path within
the budget, or the filter cannot make it stand), the next-nearest library motion is tried; the
result lists every attempt and why it failed.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from robot_rise.errors import PostureError
from robot_rise.filter import FilterResult, FilterSettings, dynamics_filter, join_with_blend
from robot_rise.library import Connection, KMeansTree, MotionLibrary, load_library
from robot_rise.model import Robot
from robot_rise.planning.bench_problems import align_to_start
from robot_rise.planning.problem import PlanningProblem
from robot_rise.planning.to_trajectory import plan_trajectory
from robot_rise.posture import Posture, validate_posture
from robot_rise.trajectory import Trajectory
from robot_rise.validity import ValidityChecker

__all__ = ["RiseAttempt", "RiseResult", "rise", "connection_candidates", "connecting_posture"]

log = logging.getLogger(__name__)

DEFAULT_CANDIDATES = 3  # library motions tried, nearest first


@dataclass(frozen=True)
class RiseAttempt:
    """One candidate tried: which motion and frame, and what became of it."""

    motion: str
    frame: int
    distance: float
    planned: bool
    plan_reason: str = ""
    proven: bool = False
    filter_reason: str = ""
    seconds: dict[str, float] = field(default_factory=dict)

    def describe(self) -> str:
        if not self.planned:
            return f"{self.motion}@{self.frame}: no path ({self.plan_reason})"
        if not self.proven:
            return f"{self.motion}@{self.frame}: not proven ({self.filter_reason})"
        return f"{self.motion}@{self.frame}: proven"


@dataclass(frozen=True)
class RiseResult:
    """Outcome of :func:`rise`. ``trajectory`` is set whenever a motion was filtered (even unproven)."""

    ok: bool
    trajectory: Trajectory | None
    attempts: tuple[RiseAttempt, ...]
    reason: str = ""
    filter_result: FilterResult | None = None


def connection_candidates(library: MotionLibrary, robot: Robot, start: Posture, k: int) -> list[Connection]:
    """The nearest frame of the ``k`` nearest motions (paper 000 eq. 1), nearest first.

    The very nearest comes from the K-means tree (paper 000 section 4.1); the runners-up per
    motion from the same frame index.
    """
    index = library.frame_index(robot)
    joints = start.joint_vector(robot.joint_names)
    best = KMeansTree(index).query(start.root_quat_wxyz, joints)
    q, jw = index.query_features(start.root_quat_wxyz, joints)
    d = index.distances(q, jw)
    out = [best]
    for mid, name in enumerate(index.motion_names):
        if name == best.motion:
            continue
        rows = np.flatnonzero(index.motion_id == mid)
        if rows.size:
            i = int(rows[np.argmin(d[rows])])
            out.append(index._connection(i, float(d[i]), int(rows.size)))
    out[1:] = sorted(out[1:], key=lambda c: c.distance)
    return out[:k]


def connecting_posture(library: MotionLibrary, robot: Robot, connection: Connection, start: Posture, checker: ValidityChecker) -> Posture:
    """The connecting posture of a connection, turned and placed where the robot lies."""
    motion = library.get(connection.motion)
    tr = motion.trajectory
    cols = [tr.joint_names.index(j) for j in robot.joint_names]
    root = tr.root[connection.frame] if tr.root is not None else np.concatenate([motion.start.root_pos, motion.start.root_quat_wxyz])
    goal = Posture(robot.name, root[:3], root[3:], dict(zip(robot.joint_names, tr.q[connection.frame, cols])))
    return align_to_start(goal, start, checker)


def rise(
    robot: Robot,
    start: Posture,
    *,
    scene: str | os.PathLike[str] | None = "flat",
    key: Posture | None = None,
    seed: int = 0,
    budget_s: float = 30.0,
    library: MotionLibrary | None = None,
    candidates: int = DEFAULT_CANDIDATES,
    settings: FilterSettings = FilterSettings(),
    progress: Callable[[str], None] | None = None,
) -> RiseResult:
    """Select, plan, filter and prove a get-up from ``start``.

    Args:
        robot: the robot.
        start: the lying posture (validated against the robot; must be collision-free).
        scene: the scene the robot lies in.
        key: optional key posture to pass through (paper 000 section 4.2.3, key postures).
        seed: planner seed (deterministic for a seed).
        budget_s: planning budget per candidate [s].
        library: motion library (default: the robot's shipped library).
        candidates: how many library motions to try, nearest first.
        settings: dynamics filter settings.
        progress: called with a short stage description.

    Raises:
        PostureError: the start (or key) posture does not fit the robot or is not valid in the scene.
    """
    say = progress or (lambda s: None)
    validate_posture(start, robot, where="start posture")
    checker = ValidityChecker(robot, scene)
    report = checker.check(start)
    if not report.valid:
        raise PostureError(
            f"start posture is not valid in scene {scene}: {'; '.join(report.reasons()[:3])}",
            hint="settle it first (robot-rise sample settles postures) or check it with robot-rise check-posture",
        )
    if key is not None:
        validate_posture(key, robot, where="key posture")
        if not checker.is_valid(key):
            raise PostureError(f"key posture is not valid in scene {scene}: {'; '.join(checker.check(key).reasons()[:3])}")
    library = library or load_library(robot_name=robot.library)
    attempts: list[RiseAttempt] = []
    best_unproven: FilterResult | None = None
    for conn in connection_candidates(library, robot, key or start, candidates):
        t0 = time.monotonic()
        say(f"planning to {conn.motion} frame {conn.frame} (distance {conn.distance:.2f})")
        goal = connecting_posture(library, robot, conn, key or start, checker)
        problem = PlanningProblem(start=start, goal=goal, checker=checker, key=key, budget_s=budget_s, seed=seed)
        planned = plan_trajectory(problem)
        t1 = time.monotonic()
        if not planned.solved or planned.trajectory is None:
            reason = planned.result.reason or planned.result.status.value
            attempts.append(RiseAttempt(conn.motion, conn.frame, conn.distance, False, reason, seconds={"plan": t1 - t0}))
            log.info("candidate %s@%d: no path: %s", conn.motion, conn.frame, reason)
            continue
        say(f"filtering {conn.motion} in MuJoCo")
        motion = library.get(conn.motion)
        commanded = join_with_blend(planned.trajectory, motion.trajectory, conn.frame, blend_s=settings.blend_s)
        commanded = commanded.with_report(
            **planned.trajectory.report,
            motion=conn.motion,
            connecting_frame=conn.frame,
            connecting_distance=conn.distance,
            plan_duration_s=planned.trajectory.duration_s,
        )
        result = dynamics_filter(robot, commanded, scene=scene, settings=settings, start=start)
        t2 = time.monotonic()
        attempt = RiseAttempt(
            conn.motion, conn.frame, conn.distance, True, proven=result.ok, filter_reason=result.reason,
            seconds={"plan": t1 - t0, "filter": t2 - t1},
        )
        attempts.append(attempt)
        extra: dict[str, Any] = {"attempts": [a.describe() for a in attempts], "seconds": {"plan": t1 - t0, "filter": t2 - t1}}
        if result.ok:
            tr = result.trajectory.with_report(**extra)
            return RiseResult(True, tr, tuple(attempts), "", result)
        if best_unproven is None:
            best_unproven = result
    reason = "; ".join(a.describe() for a in attempts) or "no library motion to connect to"
    tr = best_unproven.trajectory.with_report(attempts=[a.describe() for a in attempts]) if best_unproven else None
    return RiseResult(False, tr, tuple(attempts), reason, best_unproven)


