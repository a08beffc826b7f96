"""Benchmark of the energy-driven planner (paper 004) beside RRT-blossom and OMPL's RRT-Connect (issue 7): the runs.

Problems: :mod:`robot_rise.bench.energy_problems` (crossed limbs, lying60); measures:
:mod:`robot_rise.bench.energy_metrics`; tables: :mod:`robot_rise.bench.energy_tables`.

Planners, all on the same strict ``ValidityChecker`` (flat scene):

- ``energy``: ``EnergyPlanner()`` (this issue: Algorithm 2, the section 5.2 key postures, the
  linkages straightened, the section 6.2 second stage, the motion written out densely); every
  path segment verified at 5 mm of travel;
- ``rrt_blossom``: ``RRTBlossomPlanner`` (issue 5); edges at EDGE_RESOLUTION_M (10 mm);
- ``ompl_rrtconnect``: OMPL's RRT-Connect (PyPI ``ompl`` 2.x) through the shared adapter
  robot_rise/bench/ompl_adapter.py (the one bench/planning.py uses): our checker as state
  validity, our MotionValidator at EDGE_RESOLUTION_M as OMPL's motion validator;
- ablations, only when named in ``--planners``. Energy planners (``EnergyConfig``):

  - ``energy_raw``: every alpha step of Algorithms 1-2, nothing after them
    (``keyframes=False, straighten_limbs=False, second_stage=None``);
  - ``energy_keys``: the section 5.2 key postures, nothing after them
    (``straighten_limbs=False, second_stage=None``: ``second_stage=None`` alone still
    straightens the limbs); the default of the first round;
  - ``energy_s2``: the key postures, then the section 6.2 second stage (``second_stage``, its
    current parameters), without the straightening and the dense output of the second round;
  - ``energy_r1``: the default before issue 7's second round (second stage at 0.05 rad frames
    with the eq. 18 term, no straightening, no dense output);
  - ``energy_nostraighten`` / ``energy_nodense``: the default without one of those two.

  Smoothing ablations, each a pair ``energy_<x>`` (``energy_keys``' planner) / ``energy_s2_<x>``
  (``energy_s2``'s), plus RRT-blossom's where named:

  - ``energy_noshortcut`` / ``energy_s2_noshortcut``: through the shared B-spline and timing but
    with the shared smoother's random shortcutting turned off (``SmoothingConfig(shortcut_attempts=0)``).
    NOT the shared pipeline; reported beside it to show what the shortcut does to a path that is
    already short and smooth;
  - ``energy_oldsmooth`` / ``energy_s2_oldsmooth`` / ``rrt_blossom_oldsmooth``: smoothed as before
    the smoother's repair a (``tripling_only(SmoothingConfig())``), the "before" of issue 7's
    smoother change;
  - ``energy_abc`` / ``energy_s2_abc`` / ``rrt_blossom_abc``: smoothed with repairs a-c but
    without candidate d (``SmoothingConfig(try_without_shortcut=False)``).

Every solved path goes through the shared smoothing and timing (``plan_trajectory``: shortcut +
B-spline smoothing re-verified with the checker at 2.5 mm, servo-limited timing) and is measured:
success, planning time and total time (plan + smooth + time), path length (paper 000 eq. 1
metric, ``path_length``), minimum self and ground clearance of the smoothed path, integrated
squared jerk of the timed joint rows, the same jerk at a common duration (``common_duration_jerk``),
the dimensionless jerk, the root's travel and rotation along the timed path, and the timed duration.

Files: ``--out`` keeps every run as JSON (``"format": "robot-rise/bench-energy@1"``,
:func:`write_results`), ``--merge`` tables saved runs (:func:`load_rows`; it refuses, in one line
with a hint, a file of another format or a run with missing or unknown fields); ``--lying-cache``
freezes the sampled lying60 problems (:func:`robot_rise.bench.energy_problems.cached_lying60`).

Run (prints Markdown tables)::

    .venv/bin/robot-rise bench energy --sets crossed --n 5 --budget 20 --out out/bench_energy_crossed.json
    .venv/bin/robot-rise bench energy --sets lying60 --budget 10 --lying-cache out/lying60_seed1.json --out out/bench_energy_lying60.json
    .venv/bin/robot-rise bench energy --merge out/bench_energy_crossed.json out/bench_energy_lying60.json
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

from robot_rise.bench.energy_metrics import dimensionless_jerk, root_motion
from robot_rise.bench.energy_problems import PROBLEM_KINDS, CrossedProblem, cached_lying60, crossed_problems, read_bench_file
from robot_rise.errors import FormatError
from robot_rise.fileio import write_text_atomic
from robot_rise.model import load_robot
from robot_rise.planning.energy import EnergyConfig, EnergyPlanner, SecondStageConfig
from robot_rise.planning.problem import PlanningProblem, PlanResult
from robot_rise.planning.smoothing import SmoothingConfig, tripling_only
from robot_rise.planning.timing import integrated_squared_jerk
from robot_rise.validity import ValidityChecker

__all__ = [
    "BENCH_ENERGY_FORMAT",
    "BenchRow",
    "PLANNER_NAMES",
    "THREE",
    "ABLATIONS",
    "bench_planners",
    "run_benchmark",
    "load_rows",
    "write_results",
]

log = logging.getLogger(__name__)

BENCH_ENERGY_FORMAT = "robot-rise/bench-energy@1"  # the --out results file


@dataclass(frozen=True)
class BenchRow:
    """One planner on one problem (times in s, clearances in m; NaN when unsolved)."""

    planner: str
    pset: str
    kind: str
    variant: int
    solved: bool
    plan_s: float
    total_s: float
    path_length: float
    min_self_clearance_m: float
    min_ground_clearance_m: float
    jerk: float
    duration_s: float
    reason: str
    dimensionless_jerk: float = math.nan
    root_travel_m: float = math.nan
    root_rotation_rad: float = math.nan
    jerk_common_duration: float = math.nan  # filled by with_common_duration_jerk


PLANNER_NAMES = ("energy", "rrt_blossom", "ompl_rrtconnect", "energy_keys", "energy_s2", "energy_noshortcut", "energy_s2_noshortcut", "energy_raw",
                 "energy_oldsmooth", "energy_s2_oldsmooth", "rrt_blossom_oldsmooth", "energy_abc", "energy_s2_abc", "rrt_blossom_abc",
                 "energy_r1", "energy_nostraighten", "energy_nodense")
THREE = ("energy", "rrt_blossom", "ompl_rrtconnect")  # the comparison; the others are ablations
ABLATIONS = ("energy_keys", "energy_s2", "energy_noshortcut", "energy_s2_noshortcut", "energy_raw",
             "energy_oldsmooth", "energy_s2_oldsmooth", "rrt_blossom_oldsmooth",
             "energy_abc", "energy_s2_abc", "rrt_blossom_abc",
             "energy_r1", "energy_nostraighten", "energy_nodense")  # run only when named in --planners
NO_SHORTCUT = ("energy_noshortcut", "energy_s2_noshortcut")  # smoothed without the shared shortcut (not the shared pipeline)
# smoothed as before issue 7's smoother repair (hard corners only, no waypoints put back): the "before" rows
OLD_SMOOTH = ("energy_oldsmooth", "energy_s2_oldsmooth", "rrt_blossom_oldsmooth")
# smoothed with repairs a-c but without candidate d (the curve of the planner's own waypoints)
PREV_SMOOTH = ("energy_abc", "energy_s2_abc", "rrt_blossom_abc")


# The energy planner of the ablations (issue 7): the section 5.2 key postures and nothing after them
# (the first round's default; second_stage=None alone would still straighten the limbs), and those
# key postures through the section 6.2 second stage alone (no straightening, no dense output).
_KEY_POSTURES = EnergyConfig(straighten_limbs=False, second_stage=None)
_KEY_POSTURES_S2 = EnergyConfig(straighten_limbs=False, dense_output=False, second_stage=SecondStageConfig())


def bench_planners() -> list[tuple[str, Callable[[PlanningProblem], PlanResult]]]:
    from robot_rise.bench.ompl_adapter import OmplPlanner, ompl_available
    from robot_rise.planning.rrt_blossom import RRTBlossomPlanner

    out: list[tuple[str, Callable[[PlanningProblem], PlanResult]]] = [
        ("energy", EnergyPlanner()),
        ("rrt_blossom", RRTBlossomPlanner()),
        # ablations, only when asked for by name (the smoothing of each: ``_smoothing``)
        ("energy_keys", EnergyPlanner(_KEY_POSTURES)),
        ("energy_s2", EnergyPlanner(_KEY_POSTURES_S2)),
        ("energy_noshortcut", EnergyPlanner(_KEY_POSTURES)),
        ("energy_s2_noshortcut", EnergyPlanner(_KEY_POSTURES_S2)),
        ("energy_raw", EnergyPlanner(EnergyConfig(keyframes=False, straighten_limbs=False, second_stage=None))),  # Algorithm 1's raw alpha steps
        ("energy_oldsmooth", EnergyPlanner(_KEY_POSTURES)),
        ("energy_s2_oldsmooth", EnergyPlanner(_KEY_POSTURES_S2)),
        ("rrt_blossom_oldsmooth", RRTBlossomPlanner()),
        ("energy_abc", EnergyPlanner(_KEY_POSTURES)),
        ("energy_s2_abc", EnergyPlanner(_KEY_POSTURES_S2)),
        ("rrt_blossom_abc", RRTBlossomPlanner()),
        # issue 7, second round: the default before it, and the default without each of its changes
        ("energy_r1", EnergyPlanner(EnergyConfig(straighten_limbs=False, dense_output=False,
                                                 second_stage=SecondStageConfig(frame_spacing_rad=0.05, w_lm=1.0)))),
        ("energy_nostraighten", EnergyPlanner(EnergyConfig(straighten_limbs=False))),
        ("energy_nodense", EnergyPlanner(EnergyConfig(dense_output=False))),
    ]
    if ompl_available():
        out.append(("ompl_rrtconnect", OmplPlanner("RRTConnect")))
    else:
        log.warning("the ompl package is not installed: ompl_rrtconnect skipped")
    return out


def _smoothing(name: str) -> SmoothingConfig:
    """The smoothing of benchmark row ``name``: the shared default, or its ablation's (NO_SHORTCUT, PREV_SMOOTH, OLD_SMOOTH)."""
    if name in OLD_SMOOTH:
        return tripling_only(SmoothingConfig())
    if name in PREV_SMOOTH:
        return SmoothingConfig(try_without_shortcut=False)
    if name in NO_SHORTCUT:
        return SmoothingConfig(shortcut_attempts=0)
    return SmoothingConfig()


def run_benchmark(
    *,
    sets: tuple[str, ...] = ("crossed",),
    n: int = 5,
    budget_s: float = 30.0,
    seed: int = 0,
    lying_seed: int = 1,
    planners: list[str] | None = None,
    kinds: tuple[str, ...] = PROBLEM_KINDS,
    lying_per_kind: dict[str, int] | None = None,
    progress: Callable[[BenchRow], None] | None = None,
    lying_cache: str | None = None,
) -> list[BenchRow]:
    """Every planner on every problem of ``sets``; smoothing and timing through ``plan_trajectory``."""
    from robot_rise.planning.to_trajectory import path_length, path_min_clearance, plan_trajectory

    robot = load_robot()
    checker = ValidityChecker(robot, "flat")
    problems: list[tuple[str, CrossedProblem]] = []
    if "crossed" in sets:
        problems += [("crossed", p) for p in crossed_problems(robot, checker, kinds=kinds, n=n, seed=seed)]
    if "lying60" in sets:
        problems += [("lying60", p) for p in cached_lying60(robot, lying_seed, lying_per_kind, lying_cache)]
    rows: list[BenchRow] = []
    for name, planner in bench_planners():
        if planners and not any(name == p or (name.startswith(p) and name not in ABLATIONS) for p in planners):
            continue
        if not planners and name in ABLATIONS:
            continue
        smoothing = _smoothing(name)
        for pset, pr in problems:
            problem = PlanningProblem(pr.start, pr.goal, checker, budget_s=budget_s, seed=seed + pr.variant)
            t0 = time.monotonic()
            nan = math.nan
            try:
                out = plan_trajectory(problem, planner=planner, smoothing=smoothing)
            except Exception as e:  # a planner crashing is a failure of that run, not of the benchmark
                log.exception("%s on %s/%d raised", name, pr.kind, pr.variant)
                rows.append(BenchRow(name, pset, pr.kind, pr.variant, False, time.monotonic() - t0, nan, nan, nan, nan, nan, nan, repr(e)))
                if progress is not None:
                    progress(rows[-1])
                continue
            total = time.monotonic() - t0
            plan_s = out.seconds.get("plan", nan)
            if not out.solved or out.trajectory is None or out.smoothed is None:
                row = BenchRow(name, pset, pr.kind, pr.variant, False, plan_s, total, nan, nan, nan, nan, nan, out.result.reason)
            else:
                traj = out.trajectory
                clear = path_min_clearance(out.smoothed, checker)
                travel, rot = root_motion(traj.root)
                row = BenchRow(
                    name, pset, pr.kind, pr.variant, True, plan_s, total, path_length(out.smoothed, checker), clear["self"],
                    clear["ground"], integrated_squared_jerk(traj.t, traj.q), float(traj.t[-1]), "", dimensionless_jerk(traj.t, traj.q),
                    travel, rot,
                )
            rows.append(row)
            if progress is not None:
                progress(row)
            log.info("%s %s %s/%d: %s in %.2f s", name, pset, pr.kind, pr.variant, "solved" if row.solved else "failed", plan_s)
    return rows


def load_rows(paths: list[str]) -> list[BenchRow]:
    """The runs of saved ``--out`` files (``BENCH_ENERGY_FORMAT``).

    Raises:
        FormatError: a file of another format, or a run with missing or unknown fields.
    """
    names = {f.name for f in dataclasses.fields(BenchRow)}
    required = {f.name for f in dataclasses.fields(BenchRow) if f.default is dataclasses.MISSING}
    rows: list[BenchRow] = []
    for p in paths:
        for k, r in enumerate(read_bench_file(p, BENCH_ENERGY_FORMAT, fields=("runs",))["runs"]):
            if not isinstance(r, dict):
                raise FormatError(f"{p}: run {k} is not an object", hint="pass a file this benchmark wrote with --out")
            missing, unknown = sorted(required - set(r)), sorted(set(r) - names)
            wrong = ([f"lacks {', '.join(missing)}"] if missing else []) + ([f"has unknown fields {', '.join(unknown)}"] if unknown else [])
            if wrong:
                raise FormatError(f"{p}: run {k} " + "; ".join(wrong), hint=f"a run has the fields {', '.join(sorted(names))}")
            rows.append(BenchRow(**r))
    return rows


def write_results(path: str | os.PathLike[str], rows: Sequence[BenchRow], *, args: Mapping[str, Any], wall_s: float) -> None:
    """Write the ``--out`` file (``BENCH_ENERGY_FORMAT``, atomically): the runs so far, the arguments, the wall time [s]."""
    write_text_atomic(path, json.dumps({"format": BENCH_ENERGY_FORMAT, "args": dict(args), "wall_s": wall_s,
                                        "runs": [asdict(r) for r in rows]}, indent=1))
