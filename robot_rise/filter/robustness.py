"""Robustness replays: a proven trajectory replayed unchanged on a deliberately wrong model.

A nominal proof can be a fluke of the model's exact mass, friction, servo strength and timing;
``rise`` replays every proven candidate under ``ROBUSTNESS_VARIANTS`` and prefers one that
still stands.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from robot_rise.filter.config import FilterConfig
from robot_rise.filter.proof import prove
from robot_rise.model import SUPPLY_VOLTAGE_V, Robot
from robot_rise.posture import Posture
from robot_rise.sim.player import Player
from robot_rise.trajectory import Trajectory

__all__ = ["ModelVariant", "ROBUSTNESS_VARIANTS", "stands_under"]


@dataclass(frozen=True)
class ModelVariant:
    """A deliberate error between the proof's model and the real robot, for robustness replays.

    Attributes:
        label: what it is, for reports.
        mass_scale: every body's mass and inertia times this.
        friction_scale: every geom's sliding friction times this.
        voltage_scale: servo supply voltage times this (stall torque and no-load speed scale with it).
        latency_s: the targets arrive this much later [s].
    """

    label: str
    mass_scale: float = 1.0
    friction_scale: float = 1.0
    voltage_scale: float = 1.0
    latency_s: float = 0.0


# Checked by ``rise`` on every proven candidate (ours: a heavy, grippy robot whose commands arrive
# one 100 Hz control period late — a nominal proof that is a fluke of exact timing fails this).
ROBUSTNESS_VARIANTS: tuple[ModelVariant, ...] = (
    ModelVariant("mass +10 %, friction x1.33, 10 ms latency", mass_scale=1.1, friction_scale=1.2 / 0.9, latency_s=0.01),
)


def stands_under(
    robot: Robot,
    trajectory: Trajectory,
    variant: ModelVariant,
    *,
    scene: str | os.PathLike[str] | None = "flat",
    config: FilterConfig = FilterConfig(),
    start: Posture | None = None,
) -> bool:
    """Replay ``trajectory`` unchanged on the model ``variant``; True if the robot still stands
    (judge) with no self-collision beyond the tolerance. Torque is not re-checked: the model is
    deliberately wrong."""
    player = Player(robot, scene, mass_scale=variant.mass_scale, friction_scale=variant.friction_scale,
                    voltage_v=SUPPLY_VOLTAGE_V * variant.voltage_scale)
    tr = trajectory
    if variant.latency_s > 0:
        tr = Trajectory(tr.robot, tr.joint_names, np.concatenate([[0.0], tr.t + variant.latency_s]), np.vstack([tr.q[:1], tr.q]), tr.start, tr.report)
    _, verdict, proof = prove(robot, tr, scene=scene, config=config, player=player, start=start)
    return bool(verdict.standing and not proof.self_collision)
