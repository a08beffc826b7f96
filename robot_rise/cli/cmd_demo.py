"""robot-rise demo: the main job on the embedded default robot, end to end, with no hardware.

sample a lying posture -> rise (select, plan, filter, prove) -> check (independent replay) ->
execute on the emulated Dynamixel bus -> HTML report. Each stage is the same command a user
would run; this module only wires them and prints where the results are.
"""

from __future__ import annotations

import argparse
import importlib.util
from pathlib import Path

from robot_rise.cli._common import Formatter, add_robot_args, load_robot_arg
from robot_rise.errors import RobotRiseError
from robot_rise.filter import prove
from robot_rise.posture import write_posture
from robot_rise.rise import rise
from robot_rise.sampling import classify_lying, sample_lying_postures
from robot_rise.trajectory import write_trajectory


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo",
        help="run the main job on the embedded robot (no hardware needed)",
        formatter_class=Formatter,
        description="Samples a settled lying posture, rises from it (plan + dynamics filter + proof), replays the\n"
        "result independently, streams it to the emulated servo bus and writes an HTML report.",
        epilog="example:\n  robot-rise demo --out out/demo --kind supine --seed 3",
    )
    p.add_argument("--out", default="out/demo", metavar="DIR", help="output directory (default: out/demo)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument("--kind", default="prone", choices=["supine", "prone", "left", "right"], help="lying kind (default: prone)")
    p.add_argument("--no-execute", action="store_true", help="skip streaming to the emulated bus")
    add_robot_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from robot_rise.cli import build_parser

    robot = load_robot_arg(args)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    print(f"robot {robot.name}: {robot.n_joints} joints, stand height {robot.stand_height_m:.3f} m (torso above soles)")
    sample = sample_lying_postures(robot, args.kind, 1, args.seed, scene=args.scene)
    posture = sample.postures[0]
    lying = out / "lying.json"
    write_posture(lying, posture)
    print(f"1. sampled a settled {classify_lying(posture.root_quat_wxyz)} posture -> {lying}")
    result = rise(robot, posture, scene=args.scene, seed=args.seed)
    if not result.ok or result.trajectory is None:
        raise RobotRiseError(f"rise failed: {result.reason}", hint="try another --seed or --kind")
    traj = out / "rise.json"
    write_trajectory(traj, result.trajectory)
    rep = result.trajectory.report
    print(f"2. rise: PROVEN via {rep['motion']} in {rep['duration_s']:.2f} s of robot time, peak torque "
          f"{rep['peak_torque_ratio']:.2f} of the envelope -> {traj}")
    _, verdict, check = prove(robot, result.trajectory, scene=args.scene)
    print(f"3. check (independent replay): {'PROVEN' if check['proven'] else 'NOT PROVEN'}; {verdict.summary()}")
    code = 0 if check["proven"] else 1
    parser = build_parser()
    if not args.no_execute:
        argv = ["execute", str(traj), "--mock", "--twin", "--yes", "--log", str(out / "execute_log.csv")]
        if args.robot:
            argv += ["--robot", args.robot]
        ns = parser.parse_args(argv)
        print("4. execute on the emulated Dynamixel bus, servos moved by the MuJoCo twin:")
        rc = ns.func(ns)
        code = code or rc
    if importlib.util.find_spec("robot_rise.cli.cmd_report") is not None:
        report_dir = out / "report"
        ns = parser.parse_args(["report", str(traj), "--out", str(report_dir), "--scene", str(args.scene)])
        rc = ns.func(ns)
        print(f"5. report: {report_dir / 'report.html'}")
        code = code or rc
    return code
