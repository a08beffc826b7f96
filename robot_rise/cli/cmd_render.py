"""robot-rise render: replay a trajectory in MuJoCo and write it as MP4, GIF or a PNG contact sheet."""

from __future__ import annotations

import argparse

from robot_rise.cli._common import Formatter, Progress, add_robot_args, load_robot_arg, load_trajectory_for, print_json
from robot_rise.errors import RobotRiseError
from robot_rise.render import CAMERA_PRESETS, CameraSpec, render
from robot_rise.sim.player import DEFAULT_HOLD_S

__all__ = ["register", "run", "add_camera_args", "camera_from_args", "load_trajectory_for"]  # re-exported from _common for callers


def add_camera_args(p: argparse.ArgumentParser) -> None:
    """The --camera, --azimuth, --elevation and --distance options."""
    p.add_argument(
        "--camera",
        default="follow",
        metavar="NAME",
        help=f"camera: {', '.join(CAMERA_PRESETS)}, or a camera of the scene (default: follow, which tracks the robot)",
    )
    p.add_argument("--azimuth", type=float, metavar="DEG", help="camera azimuth relative to the robot's final heading [deg]")
    p.add_argument("--elevation", type=float, metavar="DEG", help="camera elevation [deg], negative looks down")
    p.add_argument("--distance", type=float, metavar="M", help="camera distance to the robot [m]")


def camera_from_args(args: argparse.Namespace) -> CameraSpec:
    return CameraSpec(args.camera, azimuth_deg=args.azimuth, elevation_deg=args.elevation, distance_m=args.distance)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "render",
        help="render a trajectory replayed in MuJoCo to MP4, GIF or a PNG contact sheet",
        formatter_class=Formatter,
        description="Replays TRAJ from its start posture through the servo model (as robot-rise check does) and\n"
        "renders it offscreen, with no screen or GPU needed. The suffix of --out picks the output:\n"
        ".mp4 (H.264 video), .gif (animation) or .png (contact sheet of key frames).",
        epilog="examples:\n"
        "  robot-rise render out/rise.json --out out/rise.mp4\n"
        "  robot-rise render out/rise.json --out out/rise.png --camera side --frames 12\n"
        "  robot-rise render out/rise.json --out out/rise.gif --speed 2 --width 320 --height 240",
    )
    p.add_argument("trajectory", metavar="TRAJ", help="trajectory file (robot-rise/trajectory@1)")
    p.add_argument("--out", required=True, metavar="FILE", help="output file: .mp4, .gif or .png")
    add_camera_args(p)
    p.add_argument("--width", type=int, metavar="PX", help="frame width (default: 640 mp4, 400 gif, 320 png tile)")
    p.add_argument("--height", type=int, metavar="PX", help="frame height (default: 480 mp4, 300 gif, 240 png tile)")
    p.add_argument("--fps", type=float, help="video frame rate (default: 30 mp4, 15 gif)")
    p.add_argument("--speed", type=float, default=1.0, help="playback speed, x real time (default: 1)")
    p.add_argument("--frames", type=int, default=8, metavar="N", help="key frames of a .png contact sheet (default: 8)")
    p.add_argument(
        "--shadows",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="draw shadows (default: on for .png, off for videos: they cost 2/3 of the frame rate)",
    )
    p.add_argument("--hold", type=float, default=DEFAULT_HOLD_S, metavar="S", help=f"seconds the last targets are held (default: {DEFAULT_HOLD_S:g})")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    add_robot_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    robot = load_robot_arg(args)
    tr = load_trajectory_for(robot, args.trajectory)
    if args.hold < 0:
        raise RobotRiseError("--hold must be >= 0")
    with Progress("render", unit="frame") as progress:
        result = render(
            robot,
            tr,
            args.out,
            scene=args.scene,
            camera=camera_from_args(args),
            width=args.width,
            height=args.height,
            fps=args.fps,
            speed=args.speed,
            key_frames=args.frames,
            shadows=args.shadows,
            hold_s=args.hold,
            progress=progress,
            stage=progress.stage,
        )
    if args.json:
        print_json(result.as_dict())
    else:
        what = f"{result.n_frames} key frames" if result.kind == "png" else f"{result.n_frames} frames at {result.fps:g} fps"
        print(f"wrote {result.path}: {what}, {result.width}x{result.height}, {result.duration_s:.2f} s of motion")
        print(f"  rendered at {result.render_fps:.1f} frames/s ({result.backend})")
    return 0
