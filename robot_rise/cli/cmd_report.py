"""robot-rise report: one self-contained HTML page about a trajectory (video, plots, verdict, numbers)."""

from __future__ import annotations

import argparse
from pathlib import Path

from robot_rise.cli._common import Formatter, Progress, add_robot_args, load_robot_arg, print_json
from robot_rise.cli._common import load_trajectory_for
from robot_rise.cli.cmd_render import add_camera_args, camera_from_args
from robot_rise.errors import RobotRiseError
from robot_rise.proof import ProofConfig
from robot_rise.report import ReportResult, write_report

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "report",
        help="write one self-contained HTML report of a trajectory",
        formatter_class=Formatter,
        description="Replays TRAJ from its start posture through the servo model, judges it (as robot-rise check\n"
        "does) and writes DIR/report.html: the video and key frames, joint targets vs simulated positions,\n"
        "servo torque against the torque-speed envelope, ZMP and support polygon, contacts over time, the\n"
        "judge's verdict and every number of the trajectory's report. Everything is embedded in the page.\n"
        "Exit code 0 if the trajectory is proven (stands within limits), 1 if not; the page is written either way.",
        epilog="examples:\n  robot-rise report out/rise.json --out out/report\n  robot-rise report out/rise.json --out out/report --no-video --camera side",
    )
    p.add_argument("trajectory", metavar="TRAJ", help="trajectory file (robot-rise/trajectory@1)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory (report.html and video.mp4 go there)")
    add_camera_args(p)
    p.add_argument("--no-video", action="store_true", help="key frames only (faster)")
    p.add_argument("--frames", type=int, default=8, metavar="N", help="key frames (default: 8)")
    p.add_argument("--margin", type=float, default=ProofConfig().envelope_margin, help="envelope margin of the check (default: 0.10)")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    add_robot_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    robot = load_robot_arg(args)
    tr = load_trajectory_for(robot, args.trajectory)
    if not 0 <= args.margin < 1:
        raise RobotRiseError("--margin must be in [0, 1)")
    with Progress("report", unit="frame") as progress:
        result = write_report(
            robot,
            tr,
            args.out,
            scene=args.scene,
            name=Path(args.trajectory).name,
            camera=camera_from_args(args),
            video=not args.no_video,
            key_frames=args.frames,
            proof_config=ProofConfig(envelope_margin=args.margin),
            progress=progress,
            stage=progress.stage,
        )
    if args.json:
        print_json(result.as_dict())
    else:
        for line in report_lines(result):
            print(line)
    return 0 if result.proof.proven else 1


def report_lines(result: ReportResult) -> list[str]:
    """What the report command prints about a written report (also printed by ``demo``)."""
    lines = [f"wrote {result.path} ({result.size_bytes / 1e6:.1f} MB, {result.n_images} images{', video' if result.video else ''})",
             f"  {'PROVEN' if result.proof.proven else 'NOT PROVEN'}: {result.verdict.summary()}"]
    return lines + [f"  problem: {line}" for line in result.proof.problems]
