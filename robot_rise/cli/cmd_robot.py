"""robot-rise robot: inspect a robot directory, or make a scaled variant (retargeting)."""

from __future__ import annotations

import argparse

from robot_rise.cli._common import Formatter, load_robot_arg
from robot_rise.model import compose
from robot_rise.retarget import BodyScale, scale_robot


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("robot", help="inspect a robot or make a scaled variant", formatter_class=Formatter,
                       epilog="example:\n  robot-rise robot scale --arms 1.3 --torso 1.2 --out robots/op3_long")
    rsub = p.add_subparsers(dest="robot_command", metavar="ACTION", required=True)
    show = rsub.add_parser("show", help="joints, limits, servos, mass", formatter_class=Formatter,
                           epilog="example:\n  robot-rise robot show --robot configs/robots/op3")
    show.add_argument("--robot", metavar="DIR", help="robot directory (default: the embedded robot)")
    show.set_defaults(func=run_show)
    sc = rsub.add_parser("scale", help="write a robot directory with scaled arms, legs and torso",
                         formatter_class=Formatter,
                         epilog="example:\n  robot-rise robot scale --arms 1.3 --torso 1.2 --out robots/op3_long\n"
                         "  robot-rise rise --robot robots/op3_long --from lying.json --out rise.json")
    sc.add_argument("--robot", metavar="DIR", help="source robot directory (default: the embedded robot)")
    sc.add_argument("--out", required=True, metavar="DIR", help="new robot directory")
    sc.add_argument("--arms", type=float, default=1.0, help="arm segment length factor (default 1.0)")
    sc.add_argument("--legs", type=float, default=1.0, help="leg segment length factor (default 1.0)")
    sc.add_argument("--torso", type=float, default=1.0, help="torso length factor (default 1.0)")
    sc.add_argument("--name", help="new robot name (default: <source>_scaled)")
    sc.set_defaults(func=run_scale)


def run_show(args: argparse.Namespace) -> int:
    robot = load_robot_arg(args)
    m = compose(robot, None)
    print(f"robot {robot.name} ({robot.directory}); library {robot.library}")
    print(f"  mass {m.body_mass.sum():.3f} kg, stand height {robot.stand_height_m:.3f} m (torso above soles)")
    for s, lo, hi in zip(robot.servos, robot.joint_lower, robot.joint_upper):
        print(f"  id {s.id:2d} {s.joint:12s} {s.model:11s} [{lo:+.3f}, {hi:+.3f}] rad")
    return 0


def run_scale(args: argparse.Namespace) -> int:
    src = load_robot_arg(args)
    robot = scale_robot(src, args.out, BodyScale(arms=args.arms, legs=args.legs, torso=args.torso), name=args.name)
    m = compose(robot, None)
    print(f"wrote {args.out}: robot {robot.name}, mass {m.body_mass.sum():.3f} kg, stand height {robot.stand_height_m:.3f} m")
    return 0
