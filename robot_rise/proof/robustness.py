"""Robustness replays: a trajectory replayed unchanged on one deliberately wrong model.

The ensemble proof (``ensemble.py``) replays every variant of ``robot_rise.sim.variants``;
``stands_under`` is one such replay, for benchmarks and tests that ask about one variant.
"""

from __future__ import annotations

import os

from robot_rise.proof.config import ProofConfig
from robot_rise.proof.verdict import prove
from robot_rise.model import Robot
from robot_rise.posture import Posture
from robot_rise.sim.player import Player
from robot_rise.sim.variants import ModelVariant, variant_start, variant_trajectory
from robot_rise.trajectory import Trajectory

__all__ = ["stands_under"]


def stands_under(
    robot: Robot,
    trajectory: Trajectory,
    variant: ModelVariant,
    *,
    scene: str | os.PathLike[str] | None = "flat",
    config: ProofConfig = ProofConfig(),
    start: Posture | None = None,
) -> bool:
    """Replay ``trajectory`` unchanged on the model ``variant``; True if the robot still stands
    (judge) with no self-collision beyond the tolerance. Torque is not re-checked: the model is
    deliberately wrong."""
    player = Player(robot, scene, variant=variant)
    start = variant_start(start or trajectory.start, robot, variant)
    _, verdict, proof = prove(robot, variant_trajectory(trajectory, variant), scene=scene, config=config, player=player, start=start)
    return bool(verdict.standing and not proof.self_collision)
