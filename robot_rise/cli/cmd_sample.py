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
    p.add_argument("--force", action="store_true", help="replace posture files that exist (default: refuse, write nothing)")
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
    if args.kind != "any":  # the names are known before sampling: refuse at once
        _refuse_existing([_path(out, args.kind, args.seed, i) for i in range(args.n)], args.force)
    result = sample_lying(
        robot, args.kind, args.n, args.seed, scene=args.scene, max_attempts=args.max_attempts, progress=Progress("sampling", args.n, unit="posture")
    )
    paths = [_path(out, kind, args.seed, i) for i, kind in enumerate(result.kinds)]
    _refuse_existing(paths, args.force)  # before the first file is written
    out.mkdir(parents=True, exist_ok=True)
    files = []
    for path, p in zip(paths, result.postures):
        write_posture(path, p)
        files.append(str(path))
    if args.json:
        print_json({"files": files, "attempts": result.attempts, "discarded": result.discarded})
    else:
        print(f"wrote {len(files)} postures to {out} ({result.attempts} attempts)")
        for reason, count in sorted(result.discarded.items(), key=lambda kv: -kv[1]):
            print(f"  discarded {count}: {reason}")
    return 0


def _path(out: Path, kind: str, seed: int, i: int) -> Path:
    return out / f"{kind}_{seed}_{i:03d}.json"


def _refuse_existing(paths: list[Path], force: bool) -> None:
    """Refuse (one line, nothing written) when any of ``paths`` exists, unless ``force``."""
    existing = [p for p in paths if p.exists()]
    if existing and not force:
        more = f" (and {len(existing) - 1} more)" if len(existing) > 1 else ""
        raise RobotRiseError(f"{existing[0]} exists{more}: pass --force to replace, or choose another --out or --seed")
