"""robot-rise check: replay a trajectory file from its start posture; exit 0 only if it stands within limits."""

from __future__ import annotations

import argparse

from robot_rise.cli._common import Formatter, add_robot_args, load_robot_arg, load_trajectory_for, print_json
from robot_rise.errors import PostureError, RobotRiseError
from robot_rise.filter import FilterConfig, prove, scene_digest
from robot_rise.validity import ValidityChecker


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "check",
        help="replay a trajectory in MuJoCo through the servo model and judge it",
        formatter_class=Formatter,
        description="Replays TRAJ from its start posture through the Dynamixel servo model, then reports the\n"
        "standing judge's verdict, peak torque against the torque-speed envelope, balance and contacts.\n"
        "Exit code 0 only if the robot ends standing within the limits.",
        epilog="example:\n  robot-rise check out/rise.json --scene flat",
    )
    p.add_argument("trajectory", metavar="TRAJ", help="trajectory file (robot-rise/trajectory@1)")
    p.add_argument("--margin", type=float, default=FilterConfig().envelope_margin, help="envelope margin (default: 0.10)")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    add_robot_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    robot = load_robot_arg(args)
    tr = load_trajectory_for(robot, args.trajectory)
    if not 0 <= args.margin < 1:
        raise RobotRiseError("--margin must be in [0, 1)")
    start_report = ValidityChecker(robot, args.scene).check(tr.start)
    if not start_report.valid:
        raise PostureError(
            f"{args.trajectory}: start posture is not valid in scene {args.scene}: {'; '.join(start_report.reasons()[:3])}",
            hint="pass the --scene the trajectory was made for" + (f" ({tr.report['scene']})" if tr.report.get("scene") else ""),
        )
    proven_in = tr.report.get("scene")
    other_scene = bool(tr.report.get("scene_digest")) and tr.report.get("scene_digest") != scene_digest(args.scene)
    _, verdict, proof = prove(robot, tr, scene=args.scene, config=FilterConfig(envelope_margin=args.margin))
    if args.json:
        print_json(proof.to_dict())
    else:
        print(f"{args.trajectory}: {'PROVEN' if proof.proven else 'NOT PROVEN'} in scene {args.scene}")
        if other_scene:
            print(f"  note: the file was proven in scene {proven_in}, not this one (pass --scene {proven_in})")
        print(f"  {verdict.summary()}")
        print(f"  duration {proof.duration_s:.2f} s; ground contacts: {', '.join(proof.ground_contacts) or 'none'}")
        for line in proof.problems:
            print(f"  problem: {line}")
    return 0 if proof.proven else 1
