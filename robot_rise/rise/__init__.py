"""Rise: from a lying posture to a proven get-up, as a pipeline of small steps.

- ``options``: ``RiseOptions``, what a rise may be asked (scene, key, budget, candidates, proof).
- ``result``: ``RiseAttempt`` and ``RiseResult``, what it returns.
- ``context``: ``RiseContext`` (what rises of one robot in one scene reuse), ``select_goal``.
- ``candidate``: one candidate's approach joined to its motion, filtered and proven.
- ``recovery``: a new rise from where a failed attempt left the robot, as a loop.
- ``pipeline``: ``rise``, the passes (composed, whole, recovery) over the candidates.
"""

from __future__ import annotations

from robot_rise.rise.candidate import MORE_ITERATIONS, NOT_COMPOSABLE
from robot_rise.rise.context import GoalSelection, RiseContext, connection_room, select_goal
from robot_rise.rise.options import DEFAULT_CANDIDATE_RANK, DEFAULT_CANDIDATES, DEFAULT_RETRIES, RiseOptions
from robot_rise.rise.pipeline import MAX_STRETCH, rise
from robot_rise.rise.result import RiseAttempt, RiseResult

__all__ = [
    "rise",
    "RiseOptions",
    "RiseResult",
    "RiseAttempt",
    "RiseContext",
    "GoalSelection",
    "select_goal",
    "connection_room",
    "MORE_ITERATIONS",
    "NOT_COMPOSABLE",
    "MAX_STRETCH",
    "DEFAULT_CANDIDATES",
    "DEFAULT_CANDIDATE_RANK",
    "DEFAULT_RETRIES",
]
