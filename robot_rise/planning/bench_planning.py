"""Benchmark: our RRT-blossom against OMPL's RRT-Connect and PRM on the same problems.

Same validity checker (robot_rise.validity), same edge checking (our MotionValidator at
EDGE_RESOLUTION_M, installed into OMPL as its MotionValidator), same smoothing
(robot_rise.planning.smoothing) and the same problems: the paper 000 section 5 protocol of 60
settled lying postures on flat ground (20 supine, 20 prone, 10 left + 10 right) to their
connecting postures, plus the beam, low-bed and table scenes (several seeds each). Reported
per planner and problem set: success rate, median and 95th-percentile time (planning +
smoothing), path length in the posture metric, minimum clearance.

Run::

    .venv/bin/python -m robot_rise.planning.bench_planning --seed 1 --budget 10 --out out/bench_planning.json

OMPL (the ``ompl`` PyPI package) is a bench-only dependency; without it only ours runs.
"""

from __future__ import annotations

import argparse
import json
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from robot_rise.constants import EDGE_RESOLUTION_M
from robot_rise.model import Robot, load_robot
from robot_rise.planning.bench_problems import BenchProblem, lying_problems, obstacle_problems
from robot_rise.planning.motion_validator import MotionValidator
from robot_rise.planning.problem import PlanningProblem, PlanResult, PlanStatus
from robot_rise.planning.refine import RRTBlossomPlanner, states_to_sequence
from robot_rise.planning.smoothing import smooth_path
from robot_rise.planning.space import PostureSpace
from robot_rise.planning.to_trajectory import path_length, path_min_clearance
from robot_rise.validity import ValidityChecker

__all__ = ["OmplPlanner", "run_benchmark", "main"]

log = logging.getLogger(__name__)


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


@dataclass(frozen=True)
class _Row:
    planner: str
    problem: str
    pset: str
    seed: int
    solved: bool
    seconds: float
    length: float
    clearance_m: float
    reason: str


def _run_one(planner: Callable[[PlanningProblem], PlanResult], name: str, prob: BenchProblem, pset: str, checker: ValidityChecker, seed: int, budget: float) -> _Row:
    t0 = time.monotonic()
    res = planner(PlanningProblem(prob.start, prob.goal, checker, budget_s=budget, seed=seed))
    if not res.solved or res.path is None:
        return _Row(name, prob.name, pset, seed, False, time.monotonic() - t0, float("nan"), float("nan"), res.reason[:200])
    sm = smooth_path(res.path, checker, seed=seed)
    dt = time.monotonic() - t0
    clear = path_min_clearance(sm, checker, stride=4)
    return _Row(name, prob.name, pset, seed, True, dt, path_length(sm, checker), min(clear.values()), "")


def run_benchmark(robot: Robot, *, seed: int, budget_s: float, planners: dict[str, Callable[[PlanningProblem], PlanResult]], obstacle_seeds: int = 5, n_flat: int = 20) -> list[_Row]:
    """Run every planner on the flat-ground 60 and the obstacle scenes; rows per run."""
    flat = lying_problems(robot, n_flat, seed, per_kind={"left": n_flat // 2, "right": n_flat - n_flat // 2})
    obst = obstacle_problems(robot)
    checkers: dict[str, ValidityChecker] = {}
    rows: list[_Row] = []
    for name, planner in planners.items():
        for prob in flat:
            c = checkers.setdefault(prob.scene, ValidityChecker(robot, prob.scene))
            rows.append(_run_one(planner, name, prob, "flat60", c, seed, budget_s))
            log.info("%s %s %s %.2fs", name, prob.name, rows[-1].solved, rows[-1].seconds)
        for prob in obst:
            c = checkers.setdefault(prob.scene, ValidityChecker(robot, prob.scene))
            for s in range(obstacle_seeds):
                rows.append(_run_one(planner, name, prob, prob.scene, c, s, budget_s))
                log.info("%s %s seed %d %s %.2fs", name, prob.name, s, rows[-1].solved, rows[-1].seconds)
    return rows


def summarize(rows: list[_Row]) -> list[dict[str, object]]:
    out = []
    for planner in dict.fromkeys(r.planner for r in rows):
        for pset in dict.fromkeys(r.pset for r in rows):
            rs = [r for r in rows if r.planner == planner and r.pset == pset]
            ok = [r for r in rs if r.solved]
            t = np.array([r.seconds for r in ok]) if ok else np.array([np.nan])
            out.append({
                "planner": planner, "set": pset, "runs": len(rs), "success": len(ok) / max(1, len(rs)),
                "median_s": float(np.median(t)), "p95_s": float(np.percentile(t, 95)),
                "median_length": float(np.median([r.length for r in ok])) if ok else float("nan"),
                "min_clearance_m": float(min(r.clearance_m for r in ok)) if ok else float("nan"),
            })
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--budget", type=float, default=10.0)
    ap.add_argument("--n-flat", type=int, default=20, help="postures per supine/prone (lateral split in two)")
    ap.add_argument("--obstacle-seeds", type=int, default=5)
    ap.add_argument("--planners", default="rrt_blossom,ompl_rrtconnect,ompl_prm")
    ap.add_argument("--out", default="out/bench_planning.json")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    robot = load_robot()
    avail: dict[str, Callable[[PlanningProblem], PlanResult]] = {"rrt_blossom": RRTBlossomPlanner()}
    try:
        import ompl  # noqa: F401

        avail["ompl_rrtconnect"] = OmplPlanner("RRTConnect")
        avail["ompl_prm"] = OmplPlanner("PRM")
    except ImportError:
        log.warning("ompl is not installed: only rrt_blossom runs")
    planners = {k: avail[k] for k in args.planners.split(",") if k in avail}
    rows = run_benchmark(robot, seed=args.seed, budget_s=args.budget, planners=planners, obstacle_seeds=args.obstacle_seeds, n_flat=args.n_flat)
    table = summarize(rows)
    from pathlib import Path

    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps({"args": vars(args), "summary": table, "runs": [r.__dict__ for r in rows]}, indent=1, default=str))
    print("| planner | set | runs | success | median s | p95 s | median length | min clearance mm |")
    print("|---|---|---|---|---|---|---|---|")
    for t in table:
        print(f"| {t['planner']} | {t['set']} | {t['runs']} | {100 * t['success']:.0f}% | {t['median_s']:.2f} | {t['p95_s']:.2f} | {t['median_length']:.2f} | {1000 * t['min_clearance_m']:.1f} |")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
