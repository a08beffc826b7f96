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

OMPL (the ``ompl`` PyPI package) is a bench-only dependency; without it only ours runs. The OMPL
adapter lives in robot_rise/planning/ompl_adapter.py (shared with bench_energy.py).
"""

from __future__ import annotations

import argparse
import json
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from robot_rise.model import Robot, load_robot
from robot_rise.planning.bench_problems import BenchProblem, lying_problems, obstacle_problems
from robot_rise.planning.ompl_adapter import OmplPlanner  # the OMPL 2.x adapter (shared with bench_energy)
from robot_rise.planning.problem import PlanningProblem, PlanResult
from robot_rise.planning.refine import RRTBlossomPlanner
from robot_rise.planning.smoothing import smooth_path
from robot_rise.planning.to_trajectory import path_length, path_min_clearance
from robot_rise.validity import ValidityChecker

__all__ = ["OmplPlanner", "run_benchmark", "main"]

log = logging.getLogger(__name__)


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
