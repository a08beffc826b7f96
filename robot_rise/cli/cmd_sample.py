"""robot-rise sample: physically settled random lying postures."""

from __future__ import annotations

import argparse
from pathlib import Path

from robot_rise.cli._common import Formatter, Progress, add_robot_args, load_robot_arg, print_json
from robot_rise.errors import RobotRiseError
from robot_rise.posture import write_posture
from robot_rise.sampling import LYING_KINDS, sample_lying


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "sample",
        help="sample settled random lying postures",
        formatter_class=Formatter,
        description="Random joint angles within limits, a root orientation of the asked kind with random yaw,\n"
        "dropped and settled in MuJoCo with the servos holding the angles. Deterministic for a seed.",
        epilog="example:\n  robot-rise sample --kind supine --n 20 --seed 1 --out postures/supine",
    )
    p.add_argument("--kind", choices=[*LYING_KINDS, "any"], default="any", help="how the robot lies (default: any)")
    p.add_argument("--n", type=int, default=1, help="number of postures (default: 1)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument("--out", required=True, metavar="DIR", help="directory for the posture files")
    p.add_argument("--max-attempts", type=int, default=None, help="give up after this many attempts (default: 100 * n)")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    add_robot_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.n < 1:
        raise RobotRiseError("--n must be at least 1")
    robot = load_robot_arg(args)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise RobotRiseError(f"--out {out} exists and is not a directory")
    result = sample_lying(
        robot, args.kind, args.n, args.seed, scene=args.scene, max_attempts=args.max_attempts, progress=Progress("sampling", args.n)
    )
    out.mkdir(parents=True, exist_ok=True)
    files = []
    for i, (p, kind) in enumerate(zip(result.postures, result.kinds)):
        path = out / f"{kind}_{args.seed}_{i:03d}.json"
        write_posture(path, p)
        files.append(str(path))
    if args.json:
        print_json({"files": files, "attempts": result.attempts, "discarded": result.discarded})
    else:
        print(f"wrote {len(files)} postures to {out} ({result.attempts} attempts)")
        for reason, count in sorted(result.discarded.items(), key=lambda kv: -kv[1]):
            print(f"  discarded {count}: {reason}")
    return 0
