"""Benchmark of the player: physics steps per second for every library motion.

Run with::

    .venv/bin/robot-rise bench player [--library DIR] [--repeat N] [--compare DIR]

For each motion of the library (default ``configs/motions/op3``) it plays the motion nominally on
flat ground (default 3 s hold) ``--repeat`` times with one :class:`robot_rise.sim.Player` and
reports the median wall and CPU (process) time of ``Player.play`` and the physics steps per second
they give (steps = (duration + hold) / timestep). As the ceiling of any Python loop it also times
bare ``mj_step`` calls with the same controls (no recording, no checks).

``--compare DIR`` also plays every motion with another copy of the player, ``DIR/sim.py`` (and
``DIR/judge.py`` if present, whose functions replace the ones that sim.py imported from
robot_rise.sim.standing), interleaved with the current one so both see the same machine load, and reports
the speed-up (:func:`player_table`). To compare with the last commit::

    mkdir -p /tmp/before && git show HEAD:robot_rise/sim/player.py > /tmp/before/sim.py \\
        && git show HEAD:robot_rise/sim/standing.py > /tmp/before/judge.py
    .venv/bin/robot-rise bench player --compare /tmp/before

Single thread. On a shared machine prefer the CPU times, and compare medians of repeated runs.
"""

from __future__ import annotations

import importlib.util
import platform
import statistics
import sys
import time
from pathlib import Path
from types import ModuleType

import mujoco
import numpy as np

from robot_rise.library import Motion, load_library
from robot_rise.model import load_robot
from robot_rise.sim.player import DEFAULT_HOLD_S, Player

__all__ = ["bench", "player_table"]


def _bare_steps_per_s(player: Player, motion: Motion, hold_s: float) -> float:
    """CPU steps/s of bare mj_step with the motion's controls (the ceiling for a Python loop)."""
    m, d = player.model, player.data
    tr = motion.trajectory
    cols = [tr.joint_names.index(j) for j in player.robot.joint_names]
    dt = float(m.opt.timestep)
    n_steps = int(round((tr.duration_s + hold_s) / dt))
    step_t = np.arange(n_steps) * dt
    goals = np.stack([np.interp(step_t, tr.t, tr.q[:, c]) for c in cols], axis=-1)
    acts = player.index.actuators
    player.reset(motion.start)
    ctrl = d.ctrl
    t0 = time.process_time()
    for s in range(n_steps):
        ctrl[acts] = goals[s]
        mujoco.mj_step(m, d)
    return n_steps / max(time.process_time() - t0, 1e-9)


def _load_other(directory: Path) -> ModuleType:
    """Import DIR/sim.py (and DIR/judge.py) as separate modules."""

    def load(name: str, path: Path) -> ModuleType:
        spec = importlib.util.spec_from_file_location(name, path)
        assert spec is not None and spec.loader is not None
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod  # dataclasses look their module up
        spec.loader.exec_module(mod)
        return mod

    sim = load("_bench_other_sim", directory / "sim.py")
    if (directory / "judge.py").exists():
        judge = load("_bench_other_judge", directory / "judge.py")
        for name in dir(sim):  # the functions sim.py imported from robot_rise.sim.standing
            if getattr(getattr(sim, name), "__module__", None) == "robot_rise.sim.standing" and hasattr(judge, name):
                setattr(sim, name, getattr(judge, name))
    return sim


def _time_play(player: Player, motion: Motion, hold_s: float) -> tuple[float, float]:
    w0, c0 = time.perf_counter(), time.process_time()
    player.play(motion.trajectory, motion.start, hold_s=hold_s)
    return time.perf_counter() - w0, time.process_time() - c0


def bench(library_dir: str | None, repeat: int, compare: str | None = None, hold_s: float = DEFAULT_HOLD_S) -> list[dict]:
    """Figures per motion (see the module docstring); ``before_*`` keys only with ``compare``."""
    robot = load_robot()
    library = load_library(library_dir)
    player = Player(robot, "flat")
    other = _load_other(Path(compare)).Player(robot, "flat") if compare else None
    dt = float(player.model.opt.timestep)
    rows = []
    for motion in library.motions:
        n_steps = int(round((motion.duration_s + hold_s) / dt))
        after: list[tuple[float, float]] = []
        before: list[tuple[float, float]] = []
        bare = []
        for _ in range(repeat):
            if other is not None:
                before.append(_time_play(other, motion, hold_s))
            after.append(_time_play(player, motion, hold_s))
            bare.append(_bare_steps_per_s(player, motion, hold_s))
        row = {
            "motion": motion.name,
            "duration_s": motion.duration_s,
            "steps": n_steps,
            "wall_s": statistics.median(w for w, _ in after),
            "cpu_s": statistics.median(c for _, c in after),
            "bare_steps_per_s": statistics.median(bare),
        }
        if before:
            row["before_wall_s"] = statistics.median(w for w, _ in before)
            row["before_cpu_s"] = statistics.median(c for _, c in before)
        rows.append(row)
    return rows


def player_table(rows: list[dict], *, repeat: int, library_dir: str | None = None, compare: str | None = None,
                 hold_s: float = DEFAULT_HOLD_S) -> str:
    """The figures of :func:`bench` as BENCHMARKS.md records them: the machine, a Markdown row per motion, the totals."""
    lib = library_dir or "configs/motions/op3"
    cmp = compare is not None
    head = "| motion | duration [s] | physics steps |"
    if cmp:
        head += " before wall [s] | before CPU [s] | before steps/s |"
    head += " wall [s] | CPU [s] | steps/s |"
    if cmp:
        head += " speed-up (CPU) |"
    head += " bare mj_step/s |"
    lines = [f"Machine: {platform.machine()}, Python {platform.python_version()}, mujoco {mujoco.__version__}, single thread; library {lib}",
             f"{repeat} plays per motion (medians), hold {hold_s} s, 500 Hz physics; steps/s from CPU time", "",
             head, "| --- |" + " ---: |" * (head.count("|") - 2)]
    for r in rows:
        line = f"| {r['motion']} | {r['duration_s']:.2f} | {r['steps']} |"
        if cmp:
            line += f" {r['before_wall_s']:.3f} | {r['before_cpu_s']:.3f} | {r['steps'] / r['before_cpu_s']:.0f} |"
        line += f" {r['wall_s']:.3f} | {r['cpu_s']:.3f} | {r['steps'] / r['cpu_s']:.0f} |"
        if cmp:
            line += f" {r['before_cpu_s'] / r['cpu_s']:.2f}x |"
        line += f" {r['bare_steps_per_s']:.0f} |"
        lines.append(line)
    steps = sum(r["steps"] for r in rows)
    cpu = sum(r["cpu_s"] for r in rows)
    wall = sum(r["wall_s"] for r in rows)
    summary = f"All motions: {steps} steps, {wall:.3f} s wall, {cpu:.3f} s CPU = {steps / cpu:.0f} steps/s"
    if cmp:
        bcpu = sum(r["before_cpu_s"] for r in rows)
        bwall = sum(r["before_wall_s"] for r in rows)
        summary += f"; before {bwall:.3f} s wall, {bcpu:.3f} s CPU = {steps / bcpu:.0f} steps/s; speed-up {bcpu / cpu:.2f}x CPU, {bwall / wall:.2f}x wall"
    return "\n".join([*lines, "", summary])
