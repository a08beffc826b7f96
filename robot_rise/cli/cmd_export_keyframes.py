"""robot-rise export-keyframes: a trajectory as MuJoCo keyframes of the robot's own model."""

from __future__ import annotations

import argparse
from pathlib import Path

from robot_rise.cli._common import Formatter, add_robot_args, load_robot_arg, print_json
from robot_rise.keyframe_export import write_keyframes
from robot_rise.trajectory import read_trajectory


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "export-keyframes",
        help="write a trajectory as MuJoCo keyframes (<keyframe><key .../>) of the robot's model",
        formatter_class=Formatter,
        description="Reads TRAJ (robot-rise/trajectory@1) and writes, atomically, a MuJoCo file\n"
        "<mujoco><keyframe><key name time qpos ctrl/>...</keyframe></mujoco>, one key per row (or per sample\n"
        "with --rate), for the robot's MJCF: qpos in its order (the root from the file's root rows, else\n"
        "the start posture's; passive joints solved from the driven ones), ctrl the targets of its position\n"
        "actuators. Load it with <include file=\"KEYS.xml\"/> in the robot's MJCF.",
        epilog="examples:\n  robot-rise export-keyframes out/demo/rise.json --out rise_keys.xml\n"
        "  robot-rise export-keyframes out/demo/rise.json --out rise_keys.xml --rate 30",
    )
    p.add_argument("trajectory", metavar="TRAJ", help="trajectory file (robot-rise/trajectory@1)")
    p.add_argument("--out", metavar="FILE", help="MuJoCo XML file to write (default: TRAJ with .keys.xml)")
    p.add_argument("--rate", type=float, metavar="HZ", help="resample at this rate (default: one key per row of the file)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the text")
    add_robot_args(p, scene=False)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    robot = load_robot_arg(args)
    tr = read_trajectory(args.trajectory)
    src = Path(args.trajectory)
    out = Path(args.out) if args.out else src.with_name(f"{src.stem}.keys.xml")
    keys = write_keyframes(out, robot, tr, rate_hz=args.rate, name=src.stem, source=src.name)
    nq, nu = keys.qpos.shape[1], keys.ctrl.shape[1]
    if args.json:
        print_json({"file": str(out), "keys": len(keys.names), "rate_hz": args.rate, "robot": robot.name,
                    "model": str(robot.xml_path), "nq": nq, "nu": nu, "duration_s": tr.duration_s,
                    "loop_residual": keys.loop_residual})
        return 0
    rate = f" at {args.rate:g} Hz" if args.rate is not None else ""
    print(f"wrote {out}: {len(keys.names)} keys{rate} for {robot.xml_path.name} of robot {robot.name} "
          f"(qpos {nq}, ctrl {nu}), {tr.duration_s:.2f} s")
    return 0
