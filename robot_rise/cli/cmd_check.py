"""robot-rise check: replay a trajectory file from its start posture; exit 0 only if it stands within limits."""

from __future__ import annotations

import argparse

from robot_rise.cli._common import Formatter, add_robot_args, load_robot_arg, load_trajectory_for, print_json
from robot_rise.errors import PostureError, RobotRiseError
from robot_rise.proof import EnsembleResult, ProofConfig, check, replay_random_variants, scene_digest
from robot_rise.validity import ValidityChecker


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "check",
        help="replay a trajectory in MuJoCo through the servo model and judge it",
        formatter_class=Formatter,
        description="Replays TRAJ from its start posture through the Dynamixel servo model, then reports the\n"
        "standing judge's verdict, peak torque against the torque-speed envelope, balance and contacts;\n"
        "replays it 6 times with 1e-6 rad of seeded noise on its targets (the verdict must not hang on\n"
        "the file's rounding); then replays it on every model variant of the ensemble proof (masses,\n"
        "friction, supply, gains, latency, ticks, shapes, start). Exit code 0 only if it stands within\n"
        "the limits on the nominal model, its noisy replays and every variant. --variants N also replays\n"
        "N random variants drawn from the same ranges and reports the share that stands (the margin, on\n"
        "models it was not proven on).",
        epilog="examples:\n  robot-rise check out/rise.json --scene flat\n  robot-rise check out/rise.json --variants 50 --seed 1",
    )
    p.add_argument("trajectory", metavar="TRAJ", help="trajectory file (robot-rise/trajectory@1)")
    p.add_argument("--margin", type=float, default=ProofConfig().envelope_margin, help="envelope margin (default: 0.10)")
    p.add_argument("--no-ensemble", action="store_true", help="the nominal model only (faster; not the proof standard)")
    p.add_argument("--variants", type=int, default=0, metavar="N", help="also replay N random model variants and report the share that stands")
    p.add_argument("--seed", type=int, default=0, help="seed of the random variants (default: 0)")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    add_robot_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    robot = load_robot_arg(args)
    tr = load_trajectory_for(robot, args.trajectory)
    if not 0 <= args.margin < 1:
        raise RobotRiseError("--margin must be in [0, 1)")
    if args.variants < 0:
        raise RobotRiseError("--variants must be 0 or more")
    start_report = ValidityChecker(robot, args.scene).check(tr.start)
    if not start_report.valid:
        raise PostureError(
            f"{args.trajectory}: start posture is not valid in scene {args.scene}: {'; '.join(start_report.reasons()[:3])}",
            hint="pass the --scene the trajectory was made for" + (f" ({tr.report['scene']})" if tr.report.get("scene") else ""),
        )
    proven_in = tr.report.get("scene")
    other_scene = bool(tr.report.get("scene_digest")) and tr.report.get("scene_digest") != scene_digest(args.scene)
    # the proof standard: the nominal replay, its noisy replays, the ensemble and the combined
    # variants its proof replayed (robot_rise.filter.check)
    config = ProofConfig(envelope_margin=args.margin, ensemble=not args.no_ensemble)
    proof = check(robot, tr, scene=args.scene, config=config)
    randoms = replay_random_variants(robot, tr, args.variants, args.seed, scene=args.scene, config=config) if args.variants else None
    if args.json:
        print_json({**proof.to_dict(), **({"random_variants": _random_summary(randoms, args.seed)} if randoms else {})})
    else:
        print(f"{args.trajectory}: {'PROVEN' if proof.proven else 'NOT PROVEN'} in scene {args.scene}")
        if other_scene:
            print(f"  note: the file was proven in scene {proven_in}, not this one (pass --scene {proven_in})")
        print(f"  {proof.judge}")
        print(f"  duration {proof.duration_s:.2f} s; ground contacts: {', '.join(proof.ground_contacts) or 'none'}")
        if config.noise_replays:
            broken = sum(line.startswith("target noise") for line in proof.problems)
            print(f"  target noise +-{config.noise_rad:g} rad: {config.noise_replays - broken} of {config.noise_replays} noisy replays hold")
        if proof.ensemble:
            print(f"  ensemble: {proof.ensemble_standing} of {len(proof.ensemble)} model variants stand; worst tilt "
                  f"{proof.worst_tilt_deg:.1f} deg, height {100 * proof.worst_height_fraction:.0f} % of stand, "
                  f"torque {proof.worst_torque_ratio:.2f} of the envelope")
        for line in proof.problems:
            print(f"  problem: {line}")
        if randoms:
            r = _random_summary(randoms, args.seed)
            print(f"  random variants (seed {args.seed}): {r['standing']} of {r['n']} stand ({100 * r['share']:.0f} %); "
                  f"final tilt median {r['tilt_deg_median']:.1f} deg, max {r['tilt_deg_max']:.1f} deg; "
                  f"peak torque median {r['torque_ratio_median']:.2f}")
    return 0 if proof.proven else 1


def _random_summary(result: EnsembleResult, seed: int) -> dict:
    import numpy as np

    vs = result.verdicts
    tilt = np.array([v.final_tilt_deg for v in vs])
    torque = np.array([v.peak_torque_ratio for v in vs])
    return {"seed": seed, "n": len(vs), "standing": sum(v.standing for v in vs), "share": result.standing_share,
            "tilt_deg_median": float(np.median(tilt)), "tilt_deg_max": float(tilt.max()),
            "torque_ratio_median": float(np.median(torque)), "failures": result.failures()}
