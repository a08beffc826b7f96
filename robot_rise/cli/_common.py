"""Shared CLI helpers: robot/scene options, progress on a terminal, JSON output."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from typing import Any

from robot_rise.errors import RobotRiseError
from robot_rise.model import Robot, load_robot
from robot_rise.posture import admit_posture
from robot_rise.trajectory import Trajectory, read_trajectory

__all__ = ["add_robot_args", "load_robot_arg", "load_trajectory_for", "Progress", "print_json", "Formatter"]


class Formatter(argparse.RawDescriptionHelpFormatter):
    """Keeps the examples in epilogs as written."""


def add_robot_args(p: argparse.ArgumentParser, *, scene: bool = True) -> None:
    p.add_argument("--robot", metavar="DIR", help="robot directory (default: the embedded OP3-class robot)")
    if scene:
        p.add_argument(
            "--scene",
            metavar="SCENE",
            default="flat",
            help="scene MJCF file or shipped scene name: flat, beam, low_bed, table, slope, icy, soft (default: flat)",
        )


def load_robot_arg(args: argparse.Namespace) -> Robot:
    return load_robot(getattr(args, "robot", None))


def load_trajectory_for(robot: Robot, path: str) -> Trajectory:
    """Read a trajectory file and check it belongs to ``robot`` and starts in a valid posture.

    A start up to four servo ticks past a joint limit is clamped into it, with one warning line
    (:func:`robot_rise.posture.admit_posture`); the rows are left as written (the executor clamps
    its targets).
    """
    tr = read_trajectory(path)
    if tr.robot != robot.name:
        raise RobotRiseError(f"{path} is for robot {tr.robot!r}, not {robot.name!r}", hint="pass --robot DIR")
    start = admit_posture(tr.start, robot, where=f"{path}: start")
    return tr if start is tr.start else dataclasses.replace(tr, start=start)


class Progress:
    """A one-line progress bar on stderr when it is a terminal; silent in pipes and CI."""

    def __init__(self, label: str, total: int, *, enabled: bool | None = None) -> None:
        self.label = label
        self.total = max(total, 1)
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.t0 = time.monotonic()

    def __call__(self, done: int, total: int | None = None) -> None:
        if not self.enabled:
            return
        total = total or self.total
        width = 30
        fill = int(width * done / max(total, 1))
        el = time.monotonic() - self.t0
        sys.stderr.write(f"\r{self.label} [{'#' * fill}{'.' * (width - fill)}] {done}/{total} {el:5.1f}s")
        sys.stderr.flush()
        if done >= total:
            sys.stderr.write("\n")

    def close(self) -> None:
        if self.enabled:
            sys.stderr.write("\n")


def print_json(obj: Any) -> None:
    print(json.dumps(obj, indent=1, default=float))
