"""robot-rise demo: the main job on the embedded default robot, end to end, with no hardware.

sample a lying posture -> rise (select, plan, filter, prove) -> check (independent replay) ->
execute on the emulated Dynamixel bus -> HTML report. Each stage calls the same function as the
command a user would run (``rise``, ``check``, ``execute``, ``report``) and prints where its results are.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from robot_rise.cli._common import Formatter, Progress, add_robot_args, load_robot_arg, print_json
from robot_rise.cli._execution import ExecutionConfig, execute_trajectory, result_lines
from robot_rise.cli.cmd_report import report_lines
from robot_rise.errors import RobotRiseError
from robot_rise.proof import Proof, prove
from robot_rise.report import write_report
from robot_rise.posture import write_posture
from robot_rise.rise import RiseOptions, rise
from robot_rise.sampling import classify_lying, sample_lying
from robot_rise.trajectory import read_trajectory, write_trajectory

# what the demo writes into --out (help examples of other commands name these; a test checks it)
LYING_FILE = "lying.json"
TRAJECTORY_FILE = "rise.json"
EXECUTE_LOG_FILE = "execute_log.csv"
REPORT_DIR = "report"
WRITES = (LYING_FILE, TRAJECTORY_FILE, EXECUTE_LOG_FILE, REPORT_DIR, f"{REPORT_DIR}/report.html")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo",
        help="run the main job on the embedded robot (no hardware needed)",
        formatter_class=Formatter,
        description="Samples a settled lying posture, rises from it (plan + dynamics filter + proof), replays the\n"
        "result independently, streams it to the emulated servo bus and writes an HTML report.",
        epilog="examples:\n  robot-rise demo --out out/demo --kind supine --seed 3\n"
        "  robot-rise demo --json > demo.json   # one JSON object; the stages on stderr",
    )
    p.add_argument("--out", default="out/demo", metavar="DIR", help="output directory (default: out/demo)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument("--kind", default="prone", choices=["supine", "prone", "left", "right"], help="lying kind (default: prone)")
    p.add_argument("--no-execute", action="store_true", help="skip streaming to the emulated bus")
    p.add_argument("--json", action="store_true", help="print one JSON object of the results (the stages go to stderr)")
    add_robot_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    robot = load_robot_arg(args)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    stream = sys.stderr if args.json else sys.stdout

    def say(line: str) -> None:
        print(line, file=stream, flush=True)

    say(f"robot {robot.name}: {robot.n_joints} joints, stand height {robot.stand_height_m:.3f} m (torso above soles)")
    sample = sample_lying(robot, args.kind, 1, args.seed, scene=args.scene)
    posture = sample.postures[0]
    lying = out / LYING_FILE
    write_posture(lying, posture)
    lying_kind = classify_lying(posture.root_quat_wxyz)
    say(f"1. sampled a settled {lying_kind} posture -> {lying}")
    result = rise(robot, posture, RiseOptions(scene=args.scene, seed=args.seed))
    if not result.proven or result.trajectory is None:
        raise RobotRiseError(f"rise failed: {result.reason}", hint="try another --seed or --kind")
    traj = out / TRAJECTORY_FILE
    write_trajectory(traj, result.trajectory)
    rep = result.trajectory.report
    proof = Proof.from_dict(rep)
    say(f"2. rise: PROVEN via {rep['motion']} in {proof.duration_s:.2f} s of robot time, peak torque "
        f"{proof.peak_torque_ratio:.2f} of the envelope -> {traj}")
    _, verdict, check = prove(robot, result.trajectory, scene=args.scene)
    say(f"3. check (independent replay): {'PROVEN' if check.proven else 'NOT PROVEN'}; {verdict.summary()}")
    code = 0 if check.proven else 1
    executed = None
    if not args.no_execute:
        say("4. execute on the emulated Dynamixel bus, servos moved by the MuJoCo twin:")
        config = ExecutionConfig(mock=True, twin=True, yes=True, log=str(out / EXECUTE_LOG_FILE))
        executed = execute_trajectory(robot, read_trajectory(traj), config, progress=stream)  # what runs is the file
        for line in result_lines(executed):
            say(line)
        code = code or executed.exit_code
    report_dir = out / REPORT_DIR
    report = write_report(robot, result.trajectory, report_dir, scene=args.scene, name=traj.name, progress=Progress("render", 1))
    for line in report_lines(report):
        say(line)
    say(f"5. report: {report_dir / 'report.html'}")
    code = code or (0 if report.proof.proven else 1)
    if args.json:
        print_json({"robot": robot.name, "exit_code": code,
                    "lying": {"file": str(lying), "kind": lying_kind},
                    "rise": {"file": str(traj), "motion": rep["motion"], "duration_s": proof.duration_s,
                             "peak_torque_ratio": proof.peak_torque_ratio},
                    "check": {"proven": check.proven, "summary": verdict.summary()},
                    "execute": executed.as_dict() if executed is not None else None,
                    "report": report.as_dict()})
    return code
