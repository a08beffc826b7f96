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

__all__ = ["PostureSequence", "PlanningProblem", "PlanStatus", "PlanResult", "Planner"]


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
