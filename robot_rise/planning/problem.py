"""What every planner shares: the problem (data), the path (result geometry), the result.

OMPL's split: the posture space geometry lives in robot_rise.posture, validity in
robot_rise.validity, and here only the problem definition and the result. A planner is any
callable ``plan(problem) -> PlanResult``; an expected failure is a status with a reason, never
an exception and never a partial path presented as success.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from robot_rise.errors import FormatError
from robot_rise.posture import Posture
from robot_rise.validity import ValidityChecker

__all__ = ["PostureSequence", "PlanningProblem", "PlanStatus", "PlanResult", "Planner", "GoalSelection", "select_goal"]


@dataclass(frozen=True)
class PostureSequence:
    """A path through posture space: K waypoints (no timing).

    Attributes:
        robot: robot name.
        joint_names: joint order of ``joints``.
        root_pos: root positions [m], shape (K, 3).
        root_quat_wxyz: root orientations, unit quaternions (w, x, y, z), shape (K, 4).
        joints: joint angles [rad], shape (K, n).
    """

    robot: str
    joint_names: tuple[str, ...]
    root_pos: np.ndarray
    root_quat_wxyz: np.ndarray
    joints: np.ndarray

    def __post_init__(self) -> None:
        k = len(self.root_pos)
        if np.shape(self.root_pos) != (k, 3) or np.shape(self.root_quat_wxyz) != (k, 4) or np.shape(self.joints) != (k, len(self.joint_names)):
            raise FormatError("PostureSequence: root_pos (K,3), root_quat_wxyz (K,4), joints (K,n) must agree")

    def __len__(self) -> int:
        return len(self.root_pos)

    def posture(self, i: int) -> Posture:
        return Posture(self.robot, self.root_pos[i], self.root_quat_wxyz[i], dict(zip(self.joint_names, self.joints[i])))

    @classmethod
    def from_postures(cls, postures: list[Posture], joint_names: tuple[str, ...]) -> PostureSequence:
        return cls(
            postures[0].robot,
            joint_names,
            np.array([p.root_pos for p in postures]),
            np.array([p.root_quat_wxyz for p in postures]),
            np.array([p.joint_vector(joint_names) for p in postures]),
        )

    def qpos(self, checker: ValidityChecker) -> np.ndarray:
        """Waypoints as qpos rows of the checker's model, shape (K, nq)."""
        q = np.tile(checker.model.qpos0, (len(self), 1))
        q[:, checker.index.qpos_root[:3]] = self.root_pos
        q[:, checker.index.qpos_root[3:]] = self.root_quat_wxyz
        q[:, checker.index.qpos_joints] = self.joints
        return q


@dataclass(frozen=True)
class PlanningProblem:
    """Plan from ``start`` to ``goal`` (optionally through ``key``) for ``checker``'s robot and scene.

    Attributes:
        start, goal: postures (goal = the connecting posture of a library motion).
        checker: the strict validity checker (robot + scene).
        key: optional user key posture to pass through.
        budget_s: wall-clock budget [s].
        seed: random seed; the same seed gives the same path.
    """

    start: Posture
    goal: Posture
    checker: ValidityChecker
    key: Posture | None = None
    budget_s: float = 30.0
    seed: int = 0


class PlanStatus(enum.Enum):
    EXACT_SOLUTION = "exact solution"
    INVALID_START = "invalid start"
    INVALID_GOAL = "invalid goal"
    TIMEOUT = "timeout"
    FAILED = "failed"


@dataclass(frozen=True)
class PlanResult:
    """Outcome of a planner. ``path`` is set only for EXACT_SOLUTION.

    Attributes:
        status: what happened.
        path: the valid posture sequence from start to goal, or None.
        reason: for failures, which constraint and which segment; empty on success.
        stats: counters and timings (iterations, nodes, checks, seconds).
    """

    status: PlanStatus
    path: PostureSequence | None = None
    reason: str = ""
    stats: dict[str, Any] = field(default_factory=dict)

    @property
    def solved(self) -> bool:
        return self.status is PlanStatus.EXACT_SOLUTION and self.path is not None


class Planner(Protocol):
    """Any planner: a problem in, a result out."""

    def __call__(self, problem: PlanningProblem) -> PlanResult: ...


@dataclass(frozen=True)
class GoalSelection:
    """Where a plan goes when the user names no goal (``select_goal``).

    Attributes:
        goal: the connecting posture, placed where the robot lies (or where the key posture is).
        key: the key posture to pass through, or None (none given, or it IS the connecting posture).
        source: ``motion@frame (candidate r)`` of the library frame, for messages and reports.
    """

    goal: Posture
    key: Posture | None
    source: str


# a key posture this close (planner distance) to its connecting posture is that library posture
KEY_IN_LIBRARY_DISTANCE = 1e-6


def select_goal(ctx: Any, start: Posture, key: Posture | None = None) -> GoalSelection:
    """The connecting posture a plan goes to, as ``robot-rise rise`` selects it.

    Paper 000 section 4.1: the nearest library posture (eq. 1) to the lying posture; with a key
    posture the plan passes through it, and "if a key posture is not a posture in our motion
    database, motion planning is applied again to connect the key posture to a posture in our
    motion database" (section 5.1): the connecting posture is then the one nearest the KEY
    posture, placed where the key posture is. Among the nearest frames of the
    ``robot_rise.rise.DEFAULT_CANDIDATES`` nearest motions (nearest first), the first whose
    placement is legal is taken (as ``rise`` moves on to its next candidate); if none is, the
    nearest, so that the planner reports why it is invalid.

    Args:
        ctx: a ``robot_rise.rise.RiseContext`` (library, frame index, K-means tree, checker of the scene).
        start: the lying posture.
        key: optional key posture.
    """
    from robot_rise.planning.space import PostureSpace
    from robot_rise.rise import DEFAULT_CANDIDATES, connecting_posture, connection_candidates

    anchor = key if key is not None else start
    tried: list[tuple[Posture, str]] = []
    for rank, conn in enumerate(connection_candidates(ctx.library, ctx.robot, anchor, DEFAULT_CANDIDATES, index=ctx.index, tree=ctx.tree)):
        goal = connecting_posture(ctx.library, ctx.robot, conn, anchor, ctx.checker)
        tried.append((goal, f"{conn.motion}@{conn.frame} (candidate {rank})"))
        if ctx.checker.is_valid(goal):
            break
    else:  # no legal placement: the nearest, so that the planner reports why it is invalid
        goal, _ = tried[0]
    source = next(s for g, s in tried if g is goal)
    if key is not None:
        space = PostureSpace.for_robot(ctx.robot)
        if float(space.distance(space.state(key), space.state(goal))) < KEY_IN_LIBRARY_DISTANCE:
            return GoalSelection(key, None, source)  # the key posture is in the library: plan to it
    return GoalSelection(goal, key, source)
