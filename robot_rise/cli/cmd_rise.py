"""robot-rise rise: from a lying posture to a proven get-up trajectory."""

from __future__ import annotations

import argparse

from robot_rise.cli._common import Formatter, Progress, add_robot_args, load_robot_arg, print_json
from robot_rise.filter import FilterConfig
from robot_rise.proof import Proof, ProofConfig
from robot_rise.library import load_library
from robot_rise.posture import read_posture
from robot_rise.rise import DEFAULT_CANDIDATES, RiseOptions, rise
from robot_rise.trajectory import write_trajectory


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "rise",
        help="plan, filter and prove a get-up from a lying posture",
        formatter_class=Formatter,
        description="Selects the nearest library motion (paper 000 eq. 1), plans a collision-free path to its\n"
        "connecting posture (RRT-blossom), joins the motion, filters it through the MuJoCo servo model\n"
        "until it stands within the torque-speed envelope, and writes the commanded targets.\n"
        "Exit code 0 only if the standing judge passes; 1 if no candidate could be proven (the file,\n"
        "if written, then says why in its report); 2 on bad input.",
        epilog="example:\n  robot-rise sample --kind prone --n 1 --seed 4 --out lying/\n"
        "  robot-rise rise --from lying/prone_4_000.json --out rise.json\n  robot-rise check rise.json",
    )
    p.add_argument("--from", dest="start", required=True, metavar="POSTURE", help="lying posture file")
    p.add_argument("--key", metavar="POSTURE", help="key posture to pass through")
    p.add_argument("--out", required=True, metavar="TRAJ", help="output trajectory file")
    p.add_argument("--seed", type=int, default=0, help="planner seed (default: 0)")
    p.add_argument("--budget", type=float, default=30.0, metavar="SECONDS", help="planning budget per candidate (default: 30)")
    p.add_argument("--candidates", type=int, default=DEFAULT_CANDIDATES, help=f"library motions to try (default: {DEFAULT_CANDIDATES})")
    p.add_argument("--margin", type=float, default=ProofConfig().envelope_margin, help="torque envelope margin (default: 0.10)")
    p.add_argument("--library", metavar="DIR", help="motion library directory (default: the robot's shipped one)")
    p.add_argument("--write-unproven", action="store_true", help="write the best unproven attempt too (exit code stays 1)")
    p.add_argument("--composed", action="store_true",
                   help="prove the get-up by composition with the library motions' start proofs where it applies "
                        "(computed here first, ~3 s per motion tried: pays off over many rises, as batch --composed "
                        "and the guard do), whole otherwise")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    add_robot_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    robot = load_robot_arg(args)
    start = read_posture(args.start, robot)
    key = read_posture(args.key, robot) if args.key else None
    library = load_library(args.library) if args.library else None
    options = RiseOptions(scene=args.scene, key=key, seed=args.seed, budget_s=args.budget, library=library, candidates=args.candidates,
                          filter_config=FilterConfig(proof=ProofConfig(envelope_margin=args.margin)), composed=args.composed)
    with Progress("rise") as progress:
        result = rise(robot, start, options, progress=progress.stage)
    wrote = False
    if result.trajectory is not None and (result.proven or args.write_unproven):
        write_trajectory(args.out, result.trajectory)
        wrote = True
    rep = result.trajectory.report if result.trajectory is not None else {}
    proof = Proof.from_dict(rep) if result.trajectory is not None else None
    if args.json:
        print_json({"proven": result.proven, "out": args.out if wrote else None, "reason": result.reason,
                    "attempts": [a.describe() for a in result.attempts], "duration_s": proof.duration_s if proof else None,
                    "peak_torque_ratio": proof.peak_torque_ratio if proof else None, "motion": rep.get("motion")})
    elif result.proven and proof is not None:
        print(f"PROVEN: {args.out} ({rep['motion']}, {proof.duration_s:.2f} s, peak torque {proof.peak_torque_ratio:.2f} of the envelope,"
              f" {rep['filter_iterations']} filter iterations)")
        print(f"  {proof.judge}")
    else:
        print(f"NOT PROVEN: {result.reason}")
        print("  nothing written" if not wrote else f"  best unproven attempt written to {args.out}")
    return 0 if result.proven else 1
