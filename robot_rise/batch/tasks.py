"""Batch tasks: one (robot, scene, lying kind, seed, index) each, with an id derived from its inputs.

The id is a digest of the robot's files (``Robot.digest()``), the scene, the kind, the seed and
the index, so the same inputs always name the same task: a re-run of a batch finds what is done
by id, and a changed robot file makes new tasks instead of silently reusing old results.

Each task samples its own posture (``sample_lying`` with one posture and a seed derived from the
batch seed and the index), so tasks are independent: any subset runs in any order, on any worker,
with the same result.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from robot_rise.errors import RobotRiseError
from robot_rise.model import Robot
from robot_rise.sampling import LYING_KINDS

__all__ = ["TASK_SCHEME", "BatchTask", "task_id", "posture_seed", "make_tasks"]

TASK_SCHEME = "robot-rise/batch-task@1"
"""Part of every id: a change of what a task computes from its inputs changes this, and so every id."""


@dataclass(frozen=True)
class BatchTask:
    """One get-up to prove.

    Attributes:
        id: :func:`task_id` of the inputs below.
        robot_dir: the robot directory the worker loads.
        robot: the robot's name.
        robot_digest: SHA-256 of the robot's files.
        scene: the scene (shipped name or MJCF path).
        kind: lying kind (supine, prone, left, right).
        seed: the batch seed (also the planner seed).
        index: the posture's index among those of its robot, scene and kind.
    """

    id: str
    robot_dir: str
    robot: str
    robot_digest: str
    scene: str
    kind: str
    seed: int
    index: int


def task_id(robot_digest: str, scene: str, kind: str, seed: int, index: int) -> str:
    """A 20-hex-digit id, the same for the same inputs on every machine."""
    text = json.dumps([TASK_SCHEME, robot_digest, scene, kind, int(seed), int(index)])
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def posture_seed(seed: int, index: int) -> int:
    """The sampler's seed of posture ``index`` of a batch seeded ``seed`` (independent streams)."""
    return int(np.random.SeedSequence([int(seed), int(index)]).generate_state(1)[0])


def make_tasks(robots: Sequence[Robot], *, n: int, seed: int, kinds: Sequence[str] = LYING_KINDS, scenes: Sequence[str] = ("flat",)) -> list[BatchTask]:
    """``n`` tasks per robot, scene and kind, in that nesting order.

    Raises:
        RobotRiseError: n < 1, an unknown kind, or no robot, kind or scene.
    """
    if n < 1:
        raise RobotRiseError(f"--n must be at least 1, got {n}")
    bad = [k for k in kinds if k not in LYING_KINDS]
    if bad:
        raise RobotRiseError(f"unknown lying kind {bad[0]!r}; choose from {', '.join(LYING_KINDS)}")
    if not robots or not kinds or not scenes:
        raise RobotRiseError("a batch needs at least one robot, kind and scene")
    tasks = []
    for robot in robots:
        digest = robot.digest()
        for scene in scenes:
            for kind in kinds:
                for i in range(n):
                    tasks.append(BatchTask(task_id(digest, str(scene), kind, seed, i), str(robot.directory), robot.name, digest, str(scene), kind, seed, i))
    return tasks
