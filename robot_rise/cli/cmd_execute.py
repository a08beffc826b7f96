"""robot-rise execute: stream a trajectory file to the servos (real bus or emulator) safely."""

from __future__ import annotations

import argparse
import sys
from dataclasses import fields

from robot_rise.cli._common import Formatter, print_json
from robot_rise.cli._execution import ExecutionConfig, execute_trajectory, result_lines

EPILOG = """examples:
  robot-rise execute out/demo/rise.json --mock --yes
  robot-rise execute out/demo/rise.json --mock --twin --yes   # does the simulated robot stand up?
  robot-rise execute getup.json --port /dev/ttyUSB0 --speed 0.5 --approach 3 --log run.csv
  robot-rise execute out/demo/rise.json --mock --twin --yes --json   # one JSON object; progress on stderr
exit code: 0 only if the whole trajectory ran without a fault; 1 on a fault; 2 on refused input.
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("execute", help="preflight, then stream a trajectory to the servos under the safety layer",
                       formatter_class=Formatter, epilog=EPILOG)
    p.add_argument("trajectory", help="trajectory JSON (robot-rise/trajectory@1)")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--port", help="serial device or pyserial URL")
    g.add_argument("--mock", action="store_true", help="emulated bus (wire timing on), starting at the trajectory's start")
    p.add_argument("--baud", type=int, help="baud rate [bit/s] (default: from servos.toml)")
    p.add_argument("--robot", metavar="DIR", help="robot directory (default: the embedded OP3)")
    p.add_argument("--speed", type=float, default=1.0, help="time scale, e.g. 0.5 = half speed (default 1)")
    p.add_argument("--approach", type=float, metavar="SECONDS",
                   help="first move slowly from the present posture to the first target (at least SECONDS)")
    p.add_argument("--rate", type=float, default=100.0, help="control rate [Hz] (default 100)")
    p.add_argument("--stop", choices=["hold", "limp"], default="hold", help="stop policy on a fault or Ctrl-C")
    p.add_argument("--allow-unproven", action="store_true",
                   help="run a trajectory whose report does not say it was proven on this robot model")
    p.add_argument("--yes", action="store_true", help="do not ask for confirmation")
    p.add_argument("--log", metavar="FILE", help="CSV log of commanded vs present per cycle")
    p.add_argument("--rt-priority", type=int, metavar="P",
                   help="stream under SCHED_FIFO priority P (1..99; needs root or CAP_SYS_NICE): less jitter on a busy host")
    p.add_argument("--cpu-idle", action="store_true",
                   help="let CPUs enter deep idle states while streaming (default: hold the kernel's CPU "
                        "wake-up latency at 0 us where permitted, as cyclictest does: punctual cycles)")
    p.add_argument("--twin", action="store_true",
                   help="with --mock: the servos move a MuJoCo simulation of the robot (does it stand?)")
    p.add_argument("--scene", help="scene of the twin (default: the scene the report says it was proven in, else flat)")
    p.add_argument("--realtime", action="store_true",
                   help="with --twin: run on the wall clock (default: a simulated clock, as fast as the CPU "
                        "allows and independent of machine load)")
    p.add_argument("--json", action="store_true",
                   help="print one JSON object of the outcome (progress lines go to stderr)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from robot_rise.model import load_robot
    from robot_rise.trajectory import read_trajectory

    robot = load_robot(args.robot)
    traj = read_trajectory(args.trajectory)
    config = ExecutionConfig(**{f.name: getattr(args, f.name) for f in fields(ExecutionConfig)})
    result = execute_trajectory(robot, traj, config, progress=sys.stderr if args.json else None)
    if args.json:
        print_json(result.as_dict())
    else:
        for line in result_lines(result):
            print(line)
    return result.exit_code
