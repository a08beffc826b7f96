"""Planning in posture space: shared problem/result types; planners in their own modules."""

from robot_rise.planning.problem import PlanningProblem, PlanResult, PlanStatus, Planner, PostureSequence

__all__ = ["PlanningProblem", "PlanResult", "PlanStatus", "Planner", "PostureSequence"]
