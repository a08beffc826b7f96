"""OMPL 2.x (PyPI ``ompl``, nanobind) adapter: an OMPL geometric planner as one of our Planners.

Shared by the planning benchmarks (bench/planning.py, issue 5; bench/energy.py, issue 7) so that
OMPL runs on exactly our validity checker and our edge checking: the state space is
R^3 x SO(3) x R^n (root position, root orientation, joints within their limits) with a compound
distance weighted like our posture metric, the state validity checker is our ValidityChecker,
and the MotionValidator is ours (robot_rise.planning.motion_validator.MotionValidator at
``resolution_m``, default EDGE_RESOLUTION_M of robot-point travel) installed into OMPL.

``ompl`` is a bench-only dependency: it is imported when a planner runs, not at module import.
"""

from __future__ import annotations

import time

import numpy as np

from robot_rise.constants import EDGE_RESOLUTION_M
from robot_rise.planning.motion_validator import MotionValidator
from robot_rise.planning.problem import PlanningProblem, PlanResult, PlanStatus
from robot_rise.planning.rrt_blossom import states_to_sequence
from robot_rise.planning.space import PostureSpace

__all__ = ["OmplPlanner", "ompl_available"]


def ompl_available() -> bool:
    """True when the ``ompl`` package imports."""
    try:
        import ompl  # noqa: F401
    except ImportError:
        return False
    return True


class OmplPlanner:
    """An OMPL geometric planner ("RRTConnect" or "PRM") on our checker and edge resolution."""

    def __init__(self, name: str, resolution_m: float = EDGE_RESOLUTION_M) -> None:
        self.name = name
        self.resolution_m = resolution_m

    def __call__(self, problem: PlanningProblem) -> PlanResult:
        from ompl import base as ob
        from ompl import geometric as og
        from ompl import util as ou

        ou.setLogLevel(ou.LogLevel.LOG_NONE) if hasattr(ou, "setLogLevel") else None
        t0 = time.monotonic()
        checker = problem.checker
        robot = checker.robot
        space = PostureSpace.for_robot(robot)
        mv = MotionValidator(checker, space, self.resolution_m)
        a, b = space.state(problem.start), space.state(problem.goal)
        for label, x, st in (("start", a, PlanStatus.INVALID_START), ("goal", b, PlanStatus.INVALID_GOAL)):
            if not mv.state_valid(x):
                return PlanResult(st, reason=f"{label} posture is invalid")
        n = space.n_joints
        ss = ob.CompoundStateSpace()
        r3 = ob.RealVectorStateSpace(3)
        lo = np.minimum(a[:3], b[:3]) - np.array([0.3, 0.3, 0.02])
        hi = np.maximum(a[:3], b[:3]) + np.array([0.3, 0.3, 0.25])
        bounds = ob.RealVectorBounds(3)
        for i in range(3):
            bounds.setLow(i, float(lo[i]))
            bounds.setHigh(i, float(hi[i]))
        r3.setBounds(bounds)
        rj = ob.RealVectorStateSpace(n)
        bj = ob.RealVectorBounds(n)
        for i in range(n):
            bj.setLow(i, float(space.lower[i]))
            bj.setHigh(i, float(space.upper[i]))
        rj.setBounds(bj)
        # weights of the compound distance mirror our planner distance (w_p, w_q on the angle, 1)
        ss.addSubspace(r3, space.position_weight)
        ss.addSubspace(ob.SO3StateSpace(), space.orientation_weight)
        ss.addSubspace(rj, 1.0)
        si = ob.SpaceInformation(ss)

        def to_np(s) -> np.ndarray:  # noqa: ANN001
            p, q, j = s[0], s[1], s[2]
            return np.array([p[0], p[1], p[2], q.w, q.x, q.y, q.z, *(j[i] for i in range(n))])

        def set_state(s, x: np.ndarray) -> None:  # noqa: ANN001
            for i in range(3):
                s[0][i] = float(x[i])
            s[1].w, s[1].x, s[1].y, s[1].z = (float(v) for v in x[3:7])
            for i in range(n):
                s[2][i] = float(x[7 + i])

        si.setStateValidityChecker(lambda s: mv.state_valid(to_np(s)))

        class _MV(ob.MotionValidator):
            def checkMotion(self, s1, s2, *rest):  # noqa: ANN001, ANN002, N802
                return mv.segment_valid(to_np(s1), to_np(s2))

        motion_validator = _MV(si)
        si.setMotionValidator(motion_validator)
        si.setup()
        start, goal = si.allocState(), si.allocState()
        set_state(start, a)
        set_state(goal, b)
        pdef = ob.ProblemDefinition(si)
        pdef.setStartAndGoalStates(start, goal, 1e-9)
        planner = {"RRTConnect": og.RRTConnect, "PRM": og.PRM}[self.name](si)
        if hasattr(planner, "setRange") and self.name == "RRTConnect":
            pass  # OMPL default range (0.2 x the space extent)
        planner.setProblemDefinition(pdef)
        planner.setup()
        ou.RNG.setSeed(int(problem.seed) + 1) if hasattr(ou, "RNG") and hasattr(ou.RNG, "setSeed") else None
        remaining = max(0.01, problem.budget_s - (time.monotonic() - t0))
        planner.solve(remaining)
        if not pdef.hasExactSolution():
            return PlanResult(PlanStatus.TIMEOUT, reason=f"OMPL {self.name}: no exact solution in {problem.budget_s} s",
                              stats={"seconds": time.monotonic() - t0})
        path = pdef.getSolutionPath()
        states = np.array([to_np(path.getState(i)) for i in range(path.getStateCount())])
        states[0], states[-1] = a, b
        return PlanResult(PlanStatus.EXACT_SOLUTION, states_to_sequence(space, states),
                          stats={"seconds": time.monotonic() - t0, "checks": mv.n_checks})
