"""Benchmark: our RRT-blossom against OMPL's RRT-Connect and PRM on the same problems (issue 5).

Same validity checker (robot_rise.validity), same edge checking (our MotionValidator at
EDGE_RESOLUTION_M, installed into OMPL as its MotionValidator), same smoothing
(robot_rise.planning.smoothing) and the same problems, read from the frozen problem set
``configs/bench/planning_problems.json`` (robot_rise.bench.problems):

- flat60: the paper 000 section 5 protocol, 60 settled lying postures on flat ground (seed 1:
  20 supine, 20 prone, 10 left + 10 right) to the connecting posture ``robot-rise rise``
  selects for each from the motion library; one planner seed (``--seed``) per problem;
- beam, low_bed, table: each scene's lying posture to its library connecting posture and to the
  crouch beyond the obstacle, ``--obstacle-seeds`` planner seeds each;
- turnover60 (``--sets turnover60``, not run by default): a stress set, the same 60 postures to
  the connecting postures of a prone-only library (supine and lateral starts must turn over).

Reported per planner and problem set: success rate, median and 95th-percentile time (planning
+ smoothing, wall clock), path length in the posture metric (of the smoothed path), minimum
clearance (smallest signed distance over the smoothed path).

Run::

    .venv/bin/robot-rise bench planning --seed 1 --budget 10 --out out/bench_planning.json

``--regenerate`` samples and selects the problems again (the library may have changed) and
overwrites ``--problems``. OMPL (the ``ompl`` PyPI package, ``pip install -e '.[bench]'``) is a
bench-only dependency; without it only ours runs. The OMPL adapter lives in
robot_rise/bench/ompl_adapter.py (shared with robot_rise/bench/energy.py).
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from robot_rise.constants import VERIFY_RESOLUTION_M
from robot_rise.fileio import write_text_atomic
from robot_rise.library import library_digest
from robot_rise.model import load_robot
from robot_rise.bench.problems import FrozenProblem, build_problem_set, load_problem_set, save_problem_set
from robot_rise.bench.ompl_adapter import OmplPlanner  # the OMPL 2.x adapter (shared with bench/energy.py)
from robot_rise.planning.motion_validator import MotionValidator
from robot_rise.planning.problem import PlanningProblem, PlanResult
from robot_rise.planning.rrt_blossom import BlossomConfig, PlannerConfig, RRTBlossomPlanner
from robot_rise.planning.smoothing import smooth_path
from robot_rise.planning.space import PostureSpace
from robot_rise.planning.to_trajectory import path_length, path_min_clearance
from robot_rise.validity import ValidityChecker

__all__ = ["OmplPlanner", "BenchRow", "PlanningBenchOptions", "available_planners", "run_one", "run_benchmark", "summarize",
           "format_table", "bench_planning", "planning_report"]

log = logging.getLogger(__name__)
BENCH_PLANNING_FORMAT = "robot-rise/bench-planning@1"  # results file of this benchmark


@dataclass(frozen=True)
class BenchRow:
    """One planner run on one problem.

    Attributes:
        seconds: planning + smoothing wall clock [s] (planning alone when unsolved).
        plan_s: planning alone [s].
        length: smoothed path length, paper 000 eq. (1) metric (NaN when unsolved).
        clearance_m: smallest signed distance over the smoothed path [m] (NaN when unsolved).
        reason: the planner's failure reason (empty when solved).
        legal_fine: the smoothed path is legal at VERIFY_RESOLUTION_M (2.5 mm), checked outside
            the timed part (smoothing assumes a legal input; a planner that checked its edges
            only at EDGE_RESOLUTION_M may hand it one that is not).
    """

    planner: str
    problem: str
    pset: str
    seed: int
    solved: bool
    seconds: float
    plan_s: float
    length: float
    clearance_m: float
    status: str
    reason: str
    legal_fine: bool = False


def run_one(planner: Callable[[PlanningProblem], PlanResult], name: str, prob: FrozenProblem, checker: ValidityChecker, seed: int, budget: float) -> BenchRow:
    """Plan, smooth (re-verified) and measure one problem."""
    t0 = time.monotonic()
    res = planner(PlanningProblem(prob.start, prob.goal, checker, budget_s=budget, seed=seed))
    t1 = time.monotonic()
    if not res.solved or res.path is None:
        return BenchRow(name, prob.name, prob.pset, seed, False, t1 - t0, t1 - t0, float("nan"), float("nan"), res.status.value, res.reason[:300])
    sm = smooth_path(res.path, checker, seed=seed)
    dt = time.monotonic() - t0
    clear = path_min_clearance(sm, checker, stride=4)
    fine = MotionValidator(checker, PostureSpace.for_robot(checker.robot), VERIFY_RESOLUTION_M)
    x = np.concatenate([sm.root_pos, sm.root_quat_wxyz, sm.joints], axis=1)
    legal = not fine.illegal_edges(x).any()
    return BenchRow(name, prob.name, prob.pset, seed, True, dt, t1 - t0, path_length(sm, checker), min(clear.values()), res.status.value, "", legal)


def run_benchmark(
    problems: list[FrozenProblem],
    *,
    seed: int,
    budget_s: float,
    planners: dict[str, Callable[[PlanningProblem], PlanResult]],
    obstacle_seeds: int = 5,
    on_row: Callable[[BenchRow], None] | None = None,
) -> list[BenchRow]:
    """Every planner on every problem: flat60/turnover60 problems once with ``seed``, the others with seeds 0..obstacle_seeds-1."""
    robot = load_robot()
    checkers: dict[str, ValidityChecker] = {}
    rows: list[BenchRow] = []
    for name, planner in planners.items():
        for prob in problems:
            c = checkers.setdefault(prob.scene, ValidityChecker(robot, prob.scene))
            for s in ([seed] if prob.pset in ("flat60", "turnover60") else range(obstacle_seeds)):
                row = run_one(planner, name, prob, c, s, budget_s)
                rows.append(row)
                log.info("%s %s seed %d: %s %.2f s %s", name, prob.name, s, "solved" if row.solved else "FAILED", row.seconds, row.reason)
                if on_row is not None:
                    on_row(row)
    return rows


def summarize(rows: list[BenchRow]) -> list[dict[str, object]]:
    out = []
    for planner in dict.fromkeys(r.planner for r in rows):
        for pset in dict.fromkeys(r.pset for r in rows):
            rs = [r for r in rows if r.planner == planner and r.pset == pset]
            ok = [r for r in rs if r.solved]
            t = np.array([r.seconds for r in ok]) if ok else np.array([np.nan])
            out.append({
                "planner": planner, "set": pset, "runs": len(rs), "solved": len(ok), "success": len(ok) / max(1, len(rs)),
                "legal_fine": sum(r.legal_fine for r in ok),
                "median_s": float(np.median(t)), "p95_s": float(np.percentile(t, 95)),
                "median_length": float(np.median([r.length for r in ok])) if ok else float("nan"),
                "min_clearance_m": float(min(r.clearance_m for r in ok)) if ok else float("nan"),
            })
    return out


def format_table(table: list[dict[str, object]]) -> str:
    """The BENCHMARKS.md table (markdown)."""
    lines = [
        "| planner | set | success | legal at 2.5 mm | median s | p95 s | median length | min clearance mm |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for t in table:
        lines.append(
            f"| {t['planner']} | {t['set']} | {t['solved']}/{t['runs']} ({100 * float(t['success']):.0f}%) | {t['legal_fine']}/{t['solved']} | {float(t['median_s']):.2f} | "  # type: ignore[arg-type]
            f"{float(t['p95_s']):.2f} | {float(t['median_length']):.2f} | {1000 * float(t['min_clearance_m']):.1f} |"  # type: ignore[arg-type]
        )
    return "\n".join(lines)


@dataclass(frozen=True)
class PlanningBenchOptions:
    """What one run of the benchmark runs; the results file records these fields as its ``args``.

    Attributes:
        seed: planner seed of the flat60 (and turnover60) problems.
        budget: planning budget per run [s].
        obstacle_seeds: planner seeds 0..N-1 per beam, low-bed and table problem.
        planners: comma-separated names of :func:`available_planners` (absent ones are skipped).
        sets: comma-separated problem sets to run.
        only: comma-separated problem names (e.g. ``left/4``) to run alone ('' for all).
        problems: the frozen problem file (None: ``configs/bench/planning_problems.json``).
        regenerate: sample and select the problems again and overwrite ``problems`` first.
        sample_seed: lying-posture sampling seed of ``regenerate``.
        turnover_library: with ``regenerate``, the prone-only library directory of the turnover60 set (commit 8e60c43).
        out: the results file (``BENCH_PLANNING_FORMAT``), rewritten after every run.
    """

    seed: int = 1
    budget: float = 10.0
    obstacle_seeds: int = 5
    planners: str = "rrt_blossom,ompl_rrtconnect,ompl_prm"
    sets: str = "flat60,beam,low_bed,table"
    only: str = ""
    problems: str | None = None
    regenerate: bool = False
    sample_seed: int = 1
    turnover_library: str | None = None
    out: str = "out/bench_planning.json"


def available_planners() -> dict[str, Callable[[PlanningProblem], PlanResult]]:
    """The planners by name: ours (and its ablation ``rrt_blossom_focused``), OMPL's RRT-Connect and PRM when installed."""
    avail: dict[str, Callable[[PlanningProblem], PlanResult]] = {
        "rrt_blossom": RRTBlossomPlanner(),
        # ablation (--planners rrt_blossom_focused): samples only near the start-goal slerp, as before the fix
        "rrt_blossom_focused": RRTBlossomPlanner(PlannerConfig(blossom=BlossomConfig(uniform_share=0.0))),
    }
    try:
        import ompl  # noqa: F401

        avail["ompl_rrtconnect"] = OmplPlanner("RRTConnect")
        avail["ompl_prm"] = OmplPlanner("PRM")
    except ImportError:
        log.warning("ompl is not installed (pip install -e '.[bench]'): only rrt_blossom runs")
    return avail


def bench_planning(options: PlanningBenchOptions) -> tuple[list[dict[str, object]], list[BenchRow]]:
    """Run the benchmark as ``options`` say: (the table of :func:`summarize`, every run).

    The results file ``options.out`` holds the runs so far after each run, and the summary at the end.
    """
    robot = load_robot()
    if options.regenerate:
        path = save_problem_set(build_problem_set(robot, seed=options.sample_seed, turnover_library=options.turnover_library),
                                robot, options.problems, seed=options.sample_seed)
        log.info("wrote %s", path)
    sets = set(options.sets.split(","))
    only = set(filter(None, options.only.split(",")))
    problems = [p for p in load_problem_set(robot, options.problems) if p.pset in sets and (not only or p.name in only)]
    avail = available_planners()
    planners = {k: avail[k] for k in options.planners.split(",") if k in avail}
    out = Path(options.out)
    done: list[BenchRow] = []
    meta = {"format": BENCH_PLANNING_FORMAT, "args": asdict(options), "library_digest_now": library_digest(robot)}

    def save(row: BenchRow) -> None:
        done.append(row)
        write_text_atomic(out, json.dumps({**meta, "runs": [asdict(r) for r in done]}, indent=1, default=str))

    rows = run_benchmark(problems, seed=options.seed, budget_s=options.budget, planners=planners, obstacle_seeds=options.obstacle_seeds, on_row=save)
    table = summarize(rows)
    write_text_atomic(out, json.dumps({**meta, "summary": table, "runs": [asdict(r) for r in rows]}, indent=1, default=str))
    return table, rows


def planning_report(table: list[dict[str, object]], rows: list[BenchRow]) -> str:
    """What ``robot-rise bench planning`` prints: the BENCHMARKS.md table, then one line per failed run."""
    return "\n".join([format_table(table)] + [f"failed: {r.planner} {r.problem} seed {r.seed}: {r.reason}" for r in rows if not r.solved])
