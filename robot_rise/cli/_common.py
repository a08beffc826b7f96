"""Shared CLI helpers: robot/scene options, progress on stderr (a bar on a terminal, lines in a pipe), JSON output."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from collections.abc import Callable
from typing import Any, TextIO

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


MIN_LINE_INTERVAL_S = 1.0  # ours: in a pipe or log, at most about one progress line a second
MAX_LINE_INTERVAL_S = 30.0  # ours: ... and one at least every 30 s while the loop reports (issue 42)
LINE_STEP_FRACTION = 0.1  # ours: between those, a line each tenth of the way


class Progress:
    """Progress of a command on stderr: a tqdm bar with ETA on a terminal, plain lines in a pipe or log.

    Call it as ``progress(done, total)`` from a loop (``total`` defaults to the constructor's; it
    may change between loops, e.g. from frames of a video to key frames), and ``progress.stage(text)``
    at the start of a stage. On a terminal a loop is a tqdm bar (elapsed, rate, ETA) and a stage a
    line above it. Elsewhere (stderr not a terminal: a pipe, a log file, CI) each is one plain line,
    with no carriage return: a stage always, a loop at its first and last step and in between at most
    every ``MIN_LINE_INTERVAL_S`` and at least every ``MAX_LINE_INTERVAL_S`` (while it reports), else
    each ``LINE_STEP_FRACTION`` of the way. Usable as a context manager (closes the bar).

    Args:
        label: what is being done, first word of every line ("sampling", "batch").
        total: steps of the loop (None: stages only, or totals given per call).
        enabled: False prints nothing.
        tty: draw a bar (default: whether ``stream`` is a terminal).
        unit: what a step is, for the bar's rate ("frame", "task").
        stream: where to write (default: sys.stderr at construction).
        clock: monotonic time [s] (a fake clock in tests).
    """

    def __init__(self, label: str, total: int | None = None, *, enabled: bool | None = None, tty: bool | None = None,
                 unit: str = "it", stream: TextIO | None = None, clock: Callable[[], float] = time.monotonic) -> None:
        self.label = label
        self.total = max(total, 1) if total is not None else None
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled is not False
        self.tty = _isatty(self.stream) if tty is None else tty
        self.unit = unit
        self._clock = clock
        self.t0 = clock()
        self._loop_t0 = self.t0  # start of the current loop: its ETA comes from its own rate
        self._bar: Any = None  # the tqdm bar of the current loop (terminal only)
        self._last_line_s: float | None = None  # when the current loop last printed a line (pipe only)
        self._last_line_done = 0  # ... and at which step
        self._last_done = 0
        self._finished = False  # the current loop reached its total

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __call__(self, done: int, total: int | None = None, *, info: str = "") -> None:
        """Report ``done`` of ``total`` steps; ``info`` is shown beside (e.g. "3 proven, 0 failed")."""
        if not self.enabled:
            return
        total = max(total or self.total or 1, 1)
        if self._finished or done < self._last_done:  # a new loop
            self._new_loop()
        if self.tty:
            self._draw(done, total, info)
        else:
            self._line(done, total, info)
        self._last_done = done

    def stage(self, text: str) -> None:
        """Announce a stage: one line (above the bar on a terminal)."""
        if not self.enabled:
            return
        now = self._clock()
        line = f"{self.label} [{_interval(now - self.t0)}] {text}"
        self._loop_t0 = now  # a loop after a stage belongs to it
        if self.tty:
            from tqdm import tqdm

            tqdm.write(line, file=self.stream)
        else:
            self.stream.write(line + "\n")
            self.stream.flush()

    def close(self) -> None:
        """End the bar of the current loop (it stays on the terminal)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def _new_loop(self) -> None:
        self.close()
        if self._finished:
            self._loop_t0 = self._clock()
        self._last_line_s, self._last_line_done, self._last_done, self._finished = None, 0, 0, False

    def _draw(self, done: int, total: int, info: str) -> None:
        from tqdm import tqdm

        if self._bar is None:
            self._bar = tqdm(total=total, desc=self.label, unit=self.unit, file=self.stream, dynamic_ncols=True, leave=True)
        bar = self._bar
        if bar.total != total:
            bar.total = total
        if info:
            bar.set_postfix_str(info, refresh=False)
        bar.update(done - bar.n)
        if done >= total:
            self.close()
            self._finished = True

    def _line(self, done: int, total: int, info: str) -> None:
        now = self._clock()
        last = done >= total
        if not last and self._last_line_s is not None:
            since = now - self._last_line_s
            stepped = (done - self._last_line_done) / total >= LINE_STEP_FRACTION
            if since < MIN_LINE_INTERVAL_S or not (stepped or since >= MAX_LINE_INTERVAL_S):
                return
        loop_s = now - self._loop_t0
        eta = f", ETA {_interval(loop_s / done * (total - done))}" if 0 < done < total else ""
        more = f", {info}" if info else ""
        self.stream.write(f"{self.label} [{_interval(now - self.t0)}] {done}/{total} ({100 * done / total:.0f}%){eta}{more}\n")
        self.stream.flush()
        self._last_line_s, self._last_line_done, self._finished = now, done, last


def _interval(seconds: float) -> str:
    """``seconds`` as tqdm writes them (00:12, 1:02:03). tqdm is imported where it is used: it costs ~80 ms."""
    from tqdm import tqdm

    return tqdm.format_interval(seconds)


def _isatty(stream: TextIO) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):  # a closed or bare stream
        return False


def print_json(obj: Any) -> None:
    print(json.dumps(obj, indent=1, default=float))
