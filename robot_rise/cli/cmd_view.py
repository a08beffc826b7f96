"""robot-rise view: watch a replayed trajectory in MuJoCo's interactive viewer (needs a display)."""

from __future__ import annotations

import argparse

from robot_rise.cli._common import Formatter, add_robot_args, load_robot_arg
from robot_rise.cli._common import load_trajectory_for
from robot_rise.render import require_display, view
from robot_rise.sim.player import DEFAULT_HOLD_S, play

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "view",
        help="watch a replayed trajectory in MuJoCo's interactive viewer",
        formatter_class=Formatter,
        description="Replays TRAJ from its start posture through the servo model, then shows the replay in\n"
        "MuJoCo's interactive viewer, looping, until the window is closed. Needs a display; on a\n"
        "machine without one, use robot-rise render or robot-rise report.",
        epilog="example:\n  robot-rise view out/rise.json --speed 0.5",
    )
    p.add_argument("trajectory", metavar="TRAJ", help="trajectory file (robot-rise/trajectory@1)")
    p.add_argument("--speed", type=float, default=1.0, help="playback speed, x real time (default: 1)")
    p.add_argument("--once", action="store_true", help="play once, then close (default: loop)")
    add_robot_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    robot = load_robot_arg(args)
    tr = load_trajectory_for(robot, args.trajectory)
    require_display()  # before the replay: say so at once
    rec = play(robot, tr, scene=args.scene, hold_s=DEFAULT_HOLD_S)
    view(robot, rec, scene=args.scene, speed=args.speed, loop=not args.once)
    return 0
