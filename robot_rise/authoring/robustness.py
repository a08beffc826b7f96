"""The robustness grid a library motion must pass: nominal and the four friction/mass corners of issue 4.

A motion is verified on all five players (stands, peak torque <= ``TORQUE_BOUND`` of the
torque-speed envelope, no self collision) before it is written.
"""

from __future__ import annotations

from robot_rise.constants import ENVELOPE_MARGIN
from robot_rise.model import Robot
from robot_rise.sim.player import Player

__all__ = ["ROBUST_FRICTION", "ROBUST_MASS", "TORQUE_BOUND", "robustness_players"]

ROBUST_FRICTION = (0.5, 1.0, 1.2)  # friction scales the library must stand with (issue 4)
ROBUST_MASS = (0.9, 1.0, 1.1)  # link mass scales the library must stand with (issue 4)
TORQUE_BOUND = 1.0 - ENVELOPE_MARGIN  # peak torque / envelope at every instant, every corner (0.9)


def robustness_players(robot: Robot) -> list[Player]:
    """Players for nominal and the four friction/mass corners of issue 4 (flat ground).

    Returns:
        five players: nominal first, then (friction, mass) at (low, low), (low, high), (high, low), (high, high).
    """
    players = [Player(robot, "flat")]
    for f in (ROBUST_FRICTION[0], ROBUST_FRICTION[-1]):
        for mass in (ROBUST_MASS[0], ROBUST_MASS[-1]):
            players.append(Player(robot, "flat", friction_scale=f, mass_scale=mass))
    return players
