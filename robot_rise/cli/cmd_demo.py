"""robot-rise demo: the main job on the embedded default robot, end to end, with no hardware."""

from __future__ import annotations

import argparse
from pathlib import Path

from robot_rise.cli._common import Formatter, add_robot_args, load_robot_arg
from robot_rise.posture import write_posture
from robot_rise.sampling import classify_lying, sample_lying_postures
from robot_rise.validity import ValidityChecker


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo",
        help="run the main job on the embedded robot (no hardware needed)",
        formatter_class=Formatter,
        description="Samples a settled lying posture, checks it and prints a summary.",
        epilog="example:\n  robot-rise demo --out out/demo --seed 3",
    )
    p.add_argument("--out", default="out/demo", metavar="DIR", help="output directory (default: out/demo)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument("--kind", default="supine", choices=["supine", "prone", "left", "right"], help="lying kind (default: supine)")
    add_robot_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    robot = load_robot_arg(args)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    print(f"robot {robot.name}: {robot.n_joints} joints, stand height {robot.stand_height_m:.3f} m (torso above soles)")
    sample = sample_lying_postures(robot, args.kind, 1, args.seed, scene=args.scene)
    posture = sample.postures[0]
    path = out / "lying.json"
    write_posture(path, posture)
    report = ValidityChecker(robot, args.scene).check(posture)
    print(f"1. sampled a settled {classify_lying(posture.root_quat_wxyz)} posture ({sample.attempts} attempts) -> {path}")
    print(
        f"2. validity in scene {args.scene}: {'valid' if report.valid else 'INVALID'}; clearance ground "
        f"{report.ground_clearance_m * 1000:+.1f} mm, self {report.self_clearance_m * 1000:+.1f} mm"
    )
    for line in report.reasons():
        print(f"   {line}")
    return 0 if report.valid else 1
