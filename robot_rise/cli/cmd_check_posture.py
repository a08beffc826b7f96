"""robot-rise check-posture: validity report for one posture."""

from __future__ import annotations

import argparse

from robot_rise.cli._common import Formatter, add_robot_args, load_robot_arg, print_json
from robot_rise.posture import LIMIT_CLAMP_TOLERANCE_RAD, read_posture
from robot_rise.sampling import classify_lying
from robot_rise.validity import ValidityChecker

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "check-posture",
        help="check a posture file: limits, ground, self and obstacle collision",
        formatter_class=Formatter,
        description="Validity report for one posture; exit code 0 if valid, 1 if not, 2 if the file is bad.",
        epilog="example:\n  robot-rise check-posture postures/supine_1_000.json --scene table",
    )
    p.add_argument("posture", metavar="FILE", help="posture file (robot-rise/posture@1)")
    p.add_argument(
        "--tolerance",
        type=float,
        default=LIMIT_CLAMP_TOLERANCE_RAD,
        help=f"angles up to this far past a joint limit are clamped into it, further is an error [rad] "
        f"(default: four servo ticks, {LIMIT_CLAMP_TOLERANCE_RAD:.5f})",
    )
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    add_robot_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    robot = load_robot_arg(args)
    posture = read_posture(args.posture, robot, limit_tolerance_rad=args.tolerance)
    checker = ValidityChecker(robot, args.scene)
    report = checker.check(posture)
    if args.json:
        print_json(
            {
                "valid": report.valid,
                "lying": classify_lying(posture.root_quat_wxyz),
                "ground_clearance_m": report.ground_clearance_m,
                "self_clearance_m": report.self_clearance_m,
                "obstacle_clearance_m": report.obstacle_clearance_m,
                "problems": report.reasons(),
            }
        )
    else:
        print(f"{args.posture}: {'VALID' if report.valid else 'INVALID'} ({classify_lying(posture.root_quat_wxyz)}, scene {args.scene})")
        print(
            f"  clearance: ground {report.ground_clearance_m * 1000:+.1f} mm, self {report.self_clearance_m * 1000:+.1f} mm, "
            f"obstacles {report.obstacle_clearance_m * 1000:+.1f} mm (capped at {checker.clearance_margin_m * 1000:.0f} mm)"
        )
        for line in report.reasons():
            print(f"  {line}")
    return 0 if report.valid else 1
