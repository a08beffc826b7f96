"""RRT-blossom with loose-to-strict local refinement (paper 000 sections 3.2 and 4.2).

- ``search``: ``rrt_blossom``, the two-tree search of section 3.2 (Fig. 2) with edge viability
  (Fig. 4), one run between two states against one segment checker.
- ``refine``: ``RRTBlossomPlanner``, the planner behind the shared interface: the path planned
  loose, then made strict step by step, only its illegal segments cut out and replanned
  (sections 4.2.3-4.2.4).
"""

from robot_rise.planning.rrt_blossom.refine import (
    PlannerConfig,
    RRTBlossomPlanner,
    limbs_of_collisions,
    loose_to_strict_schedule,
    states_to_sequence,
)
from robot_rise.planning.rrt_blossom.search import BlossomConfig, BlossomOutcome, EdgeState, rrt_blossom, uniform_quaternion

__all__ = [
    "BlossomConfig",
    "BlossomOutcome",
    "EdgeState",
    "rrt_blossom",
    "uniform_quaternion",
    "PlannerConfig",
    "RRTBlossomPlanner",
    "loose_to_strict_schedule",
    "limbs_of_collisions",
    "states_to_sequence",
]
