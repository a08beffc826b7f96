"""Proven trajectories executed on the mock bus as a user first runs them: faults, clamps, band use.

Each file goes through ``robot-rise execute FILE --mock --yes`` (and with ``--twin``) in a child
process, exactly as typed: the plain mock's emulated servos, or the physics twin behind them. A
row says whether it completed, the faults the executor stopped on, the safety-clamped cycles and
how much of its tracking band (from the proof's predicted positions to the goals) it used at most.
Rise outputs to run are made here from random lying postures (``rise_outputs``).
"""

from __future__ import annotations

import dataclasses
import os
import re
import subprocess
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from robot_rise.model import Robot
from robot_rise.rise import RiseOptions, rise
from robot_rise.sampling import sample_lying_postures
from robot_rise.trajectory import write_trajectory

__all__ = ["MockRun", "execute_on_mock", "rise_outputs"]

_RATIO = re.compile(r"\(([\d.]+) of its tolerance\)")
_CLAMPED = re.compile(r"safety-clamped cycles (\d+)")


@dataclass(frozen=True)
class MockRun:
    """One ``execute --mock`` run: the file, the bus, the exit code, what the executor said."""

    file: str
    twin: bool
    exit_code: int
    faults: tuple[str, ...]
    clamped_cycles: int | None
    band_ratio: float | None
    said: str = ""  # the command's error line, where it refused or failed before streaming

    @property
    def clean(self) -> bool:
        """Completed with no fault and no clamped cycle."""
        return self.exit_code == 0 and not self.faults and self.clamped_cycles == 0


def execute_on_mock(files: Sequence[Path], robot: Robot, *, twin: bool,
                    progress: Callable[[MockRun], None] | None = None) -> list[MockRun]:
    """Every file of ``files`` executed on the mock bus (``twin``: the physics twin behind it)."""
    runs: list[MockRun] = []
    for path in files:
        cmd = [sys.executable, "-m", "robot_rise", "execute", str(path), "--robot", str(robot.directory), "--mock", "--yes"]
        done = subprocess.run(cmd + (["--twin"] if twin else []), capture_output=True, text=True, env=dict(os.environ))
        out = done.stdout + done.stderr
        ratio, clamped = _RATIO.search(out), _CLAMPED.search(out)
        run = MockRun(str(path), twin, done.returncode, tuple(l for l in out.splitlines() if l.startswith("FAULT")),
                      int(clamped.group(1)) if clamped else None, float(ratio.group(1)) if ratio else None)
        if not run.clean and not run.faults:
            errors = [l for l in out.splitlines() if l.startswith("error:")]
            run = dataclasses.replace(run, said=errors[0] if errors else (out.strip().splitlines() or [""])[-1])
        runs.append(run)
        if progress is not None:
            progress(run)
    return runs


def rise_outputs(robot: Robot, n: int, directory: Path, *, seed: int = 0) -> list[Path]:
    """``n`` proven rise outputs from random lying postures (every kind in turn), written to ``directory``."""
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for i, posture in enumerate(sample_lying_postures(robot, "any", n, seed=seed)):
        result = rise(robot, posture, RiseOptions(seed=seed + i))
        if result.proven and result.trajectory is not None:
            path = directory / f"rise_{i:03d}.json"
            write_trajectory(path, result.trajectory)
            paths.append(path)
    return paths
