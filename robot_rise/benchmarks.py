"""Benchmarks of the core (figures printed by ``robot-rise bench``, recorded in BENCHMARKS.md).

Timings are measured here, never asserted in tests: a noisy CI machine must not fail a build.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass

import numpy as np

from robot_rise.model import Robot
from robot_rise.sampling import sample_lying_postures
from robot_rise.validity import ValidityChecker

__all__ = ["ValidityBenchmark", "bench_validity"]


@dataclass(frozen=True)
class ValidityBenchmark:
    """Validity checks per second on one core, and the share of valid queries."""

    scene: str
    checks: int
    seconds: float
    checks_per_second: float
    valid_fraction: float


def bench_validity(
    robot: Robot, scene: str | os.PathLike[str] = "flat", *, n: int = 20000, seed: int = 0, perturbation_rad: float = 0.3
) -> ValidityBenchmark:
    """Time ``ValidityChecker.is_valid_qpos`` on planner-like queries.

    Queries are settled lying postures (4 of each kind) with every joint perturbed by up to
    ``perturbation_rad`` and clipped to limits, as an RRT explores around lying postures.
    """
    base = sample_lying_postures(robot, "any", 8, seed)
    checker = ValidityChecker(robot, scene)
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        p = base.postures[i % len(base.postures)]
        q = checker.qpos_of(p)
        j = checker.index.qpos_joints
        q[j] = np.clip(q[j] + rng.uniform(-perturbation_rad, perturbation_rad, len(j)), robot.joint_lower, robot.joint_upper)
        rows.append(q)
    queries = np.array(rows)
    checker.is_valid_qpos(queries[0])  # warm up
    t0 = time.perf_counter()
    valid = 0
    for q in queries:
        valid += checker.is_valid_qpos(q)
    dt = time.perf_counter() - t0
    return ValidityBenchmark(str(scene), n, dt, n / dt, valid / n)
