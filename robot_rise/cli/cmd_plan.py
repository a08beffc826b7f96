"""robot-rise plan: plan a rising path from a lying posture and write a timed trajectory."""

from __future__ import annotations

import argparse
import sys

from robot_rise.cli._common import Formatter, add_robot_args, load_robot_arg, print_json
from robot_rise.errors import RobotRiseError
from robot_rise.planning.problem import PlanningProblem
from robot_rise.planning.to_trajectory import plan_trajectory
from robot_rise.posture import read_posture
from robot_rise.trajectory import write_trajectory
from robot_rise.validity import ValidityChecker

EXIT_OK = 0
EXIT_FAILURE = 1


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "plan",
        help="plan a rising path (RRT-blossom) from a lying posture to a connecting posture",
        formatter_class=Formatter,
        description="RRT-blossom in posture space with loose-to-strict refinement (paper 000 section 4.2),\n"
        "shortcut + B-spline smoothing re-verified with the validity checker, and timing within the\n"
        "servos' velocity and acceleration limits. Writes robot-rise/trajectory@1 with the planned root\n"
        "pose per row. Deterministic for a seed. Exit 1 (no file written) when no path is found.",
        epilog="example:\n  robot-rise plan --from lying.json --to crouch.json --scene flat --seed 0 --budget 30 --out traj.json",
    )
    p.add_argument("--from", dest="start", required=True, metavar="POSTURE.json", help="the lying posture")
    p.add_argument("--to", dest="goal", metavar="POSTURE.json", help="connecting posture (overrides automatic selection)")
    p.add_argument("--key", metavar="KEY.json", help="a key posture to pass through")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument("--budget", type=float, default=30.0, metavar="SECONDS", help="planning time budget (default: 30)")
    p.add_argument("--planner", choices=["rrt-blossom", "energy"], default="rrt-blossom",
                   help="rrt-blossom (paper 000, default) or energy (paper 004, local, no random search)")
    p.add_argument("--no-smooth", action="store_true", help="keep the planner's polyline (no shortcut/B-spline)")
    p.add_argument("--out", required=True, metavar="TRAJ.json", help="trajectory file to write")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    add_robot_args(p)
    p.set_defaults(func=run)


def _planner(name: str):  # noqa: ANN202
    if name == "energy":
        from robot_rise.planning.energy import EnergyPlanner

        return EnergyPlanner()
    from robot_rise.planning.rrt_blossom import RRTBlossomPlanner

    return RRTBlossomPlanner()


def run(args: argparse.Namespace) -> int:
    if args.budget <= 0:
        raise RobotRiseError("--budget must be > 0 seconds")
    robot = load_robot_arg(args)
    checker = ValidityChecker(robot, args.scene)
    start = read_posture(args.start, robot)
    key = read_posture(args.key, robot) if args.key else None
    if args.goal:
        goal = read_posture(args.goal, robot)
    else:  # the library's connecting posture (nearest the key posture when one is given)
        from robot_rise.rise import RiseContext, select_goal

        sel = select_goal(RiseContext.build(robot, args.scene), start, key)
        goal, key = sel.goal, sel.key
        print(f"connecting posture: {sel.source}" + ("" if key is not None or not args.key else " (the key posture itself)"), file=sys.stderr)
    problem = PlanningProblem(start, goal, checker, key=key, budget_s=args.budget, seed=args.seed)
    out = plan_trajectory(problem, planner=_planner(args.planner), smooth=not args.no_smooth)
    res = out.result
    if out.trajectory is None:
        if args.json:
            print_json({"status": res.status.value, "reason": res.reason, "stats": res.stats})
        print(f"no path ({res.status.value}): {res.reason}", file=sys.stderr)
        return EXIT_FAILURE
    write_trajectory(args.out, out.trajectory)
    rep = out.trajectory.report["planner"]
    summary = {
        "out": args.out,
        "status": res.status.value,
        "waypoints": rep["waypoints_planned"],
        "rows": len(out.trajectory.t),
        "duration_s": round(out.trajectory.duration_s, 3),
        "seconds": {k: round(v, 3) for k, v in out.seconds.items()},
        "path_length": round(rep["path_length"], 3),
        "min_clearance_m": {k: round(v, 4) for k, v in rep["min_clearance_m"].items()},
    }
    if args.json:
        print_json(summary)
    else:
        print(
            f"wrote {args.out}: {summary['rows']} rows, {summary['duration_s']} s of motion; planned {summary['waypoints']} "
            f"waypoints in {summary['seconds']['plan']} s, smoothed in {summary['seconds']['smooth']} s; "
            f"path length {summary['path_length']}"
        )
    return EXIT_OK
