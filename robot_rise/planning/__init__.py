"""Planning in posture space: shared problem/result types; planners in their own modules.

RRT-blossom (paper 000) lives in the ``rrt_blossom`` package (the search and the loose-to-strict
driver), the energy-driven planner (paper 004) in the ``energy`` package. ``plan_trajectory``
plans, smooths and times with any of them.
"""

from robot_rise.planning.energy import EnergyPlanner, plan_energy
from robot_rise.planning.problem import PlanningProblem, PlanResult, PlanStatus, Planner, PostureSequence
from robot_rise.planning.rrt_blossom import PlannerConfig, RRTBlossomPlanner
from robot_rise.planning.smoothing import smooth_path
from robot_rise.planning.timing import TimingLimits, time_parameterize
from robot_rise.planning.to_trajectory import plan_trajectory

__all__ = [
    "PlanningProblem",
    "PlanResult",
    "PlanStatus",
    "Planner",
    "PostureSequence",
    "RRTBlossomPlanner",
    "PlannerConfig",
    "EnergyPlanner",
    "plan_energy",
    "plan_trajectory",
    "smooth_path",
    "time_parameterize",
    "TimingLimits",
]
