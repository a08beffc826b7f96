"""Benchmark of the energy-driven planner (paper 004) beside RRT-blossom and OMPL's RRT-Connect (issue 7).

Problem sets:

- crossed-limb problems, where the straight interpolation penetrates (issue 7, "Measured"):

  - ``crossed_arms``: lying supine, forearms folded across the chest, left over right -> right over left;
  - ``crossed_legs``: lying supine, legs crossed with the left over the right -> the right over the left;
  - ``arm_under_back``: supine with the left arm under the back -> a sitting posture (torso upright,
    hips flexed 90 degrees, legs straight on the ground, hands forward).

  Each kind has ``n`` variants: the base pair with seeded joint jitter (the same jitter on both
  ends), kept only when both ends are legal and the straight motion between them is not.

- ``lying60``: the paper 000 section 5 protocol, 60 settled lying postures on flat ground
  (``sample_lying``, fixed seed: 20 supine, 20 prone, 10 left, 10 right) to their LIBRARY
  connecting postures: the nearest library frame (``robot_rise.library.connection_candidates(..., k=1)`` of
  robot_rise.rise, over the lying frames of ``RiseContext``), placed where the robot lies
  (``connecting_posture``), exactly as ``robot-rise rise`` selects its first candidate.

Planners, all on the same strict ``ValidityChecker`` (flat scene):

- ``energy``: ``EnergyPlanner()`` (this issue: Algorithm 2, the section 5.2 key postures, the
  linkages straightened, the section 6.2 second stage, the motion written out densely); every
  path segment verified at 5 mm of travel;
- ``rrt_blossom``: ``RRTBlossomPlanner`` (issue 5); edges at EDGE_RESOLUTION_M (10 mm);
- ``ompl_rrtconnect``: OMPL's RRT-Connect (PyPI ``ompl`` 2.x) through the shared adapter
  robot_rise/bench/ompl_adapter.py (the one bench_planning.py uses): our checker as state
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

Files: ``--out`` keeps every run as JSON (``"format": "robot-rise/bench-energy@1"``), ``--merge``
tables saved runs (and refuses, in one line with a hint, a file of another format or a run with
missing or unknown fields); ``--lying-cache`` freezes the sampled lying60 problems
(``"robot-rise/lying-problems@1"``; a cache from before that string is read with a warning).

Run (prints Markdown tables)::

    .venv/bin/python -m robot_rise.bench.energy --sets crossed --n 5 --budget 20 --out out/bench_energy_crossed.json
    .venv/bin/python -m robot_rise.bench.energy --sets lying60 --budget 10 --lying-cache out/lying60_seed1.json --out out/bench_energy_lying60.json
    .venv/bin/python -m robot_rise.bench.energy --merge out/bench_energy_crossed.json out/bench_energy_lying60.json
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import math
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from robot_rise.constants import ENERGY_VERIFY_RESOLUTION_M
from robot_rise.errors import FormatError, RobotRiseError
from robot_rise.model import Robot, load_robot
from robot_rise.planning.energy import EnergyConfig, EnergyPlanner, SecondStageConfig
from robot_rise.planning.motion_validator import MotionValidator
from robot_rise.planning.problem import PlanningProblem, PlanResult
from robot_rise.planning.smoothing import SmoothingConfig, tripling_only
from robot_rise.planning.timing import integrated_squared_jerk
from robot_rise.posture import Posture
from robot_rise.validity import ValidityChecker

__all__ = [
    "BENCH_ENERGY_FORMAT",
    "LYING_PROBLEMS_FORMAT",
    "CrossedProblem",
    "PROBLEM_KINDS",
    "PROBLEM_SETS",
    "LYING60_PER_KIND",
    "supine_quat_wxyz",
    "crossed_problems",
    "lying60_problems",
    "library_digest",
    "straight_motion_is_illegal",
    "integrated_squared_jerk",
    "dimensionless_jerk",
    "common_duration_jerk",
    "with_common_duration_jerk",
    "root_motion",
    "paired_jerk_table",
    "BenchRow",
    "run_benchmark",
    "summary_table",
    "main",
]

log = logging.getLogger(__name__)

BENCH_ENERGY_FORMAT = "robot-rise/bench-energy@1"  # the --out results file
LYING_PROBLEMS_FORMAT = "robot-rise/lying-problems@1"  # the --lying-cache problem file
PROBLEM_KINDS = ("crossed_arms", "crossed_legs", "arm_under_back")
JITTER_RAD = 0.05  # ours: per-joint jitter of the variants (same on both ends)
GROUND_GAP_M = 0.0005  # lying postures rest this far above the ground


@dataclass(frozen=True)
class CrossedProblem:
    """One benchmark problem: a kind, a variant number and the two postures.

    Attributes:
        goal_rank, goal_frame: lying60 only, which library candidate the goal is (0 = the nearest)
            and its ``motion@frame``; 0 and "" for the crossed-limb problems.
    """

    kind: str
    variant: int
    start: Posture
    goal: Posture
    goal_rank: int = 0
    goal_frame: str = ""


def supine_quat_wxyz() -> np.ndarray:
    """Root orientation lying on the back: the torso's +x (front) up, head toward world -x."""
    a = -math.pi / 2
    return np.array([math.cos(a / 2), 0.0, math.sin(a / 2), 0.0])


def _posture(robot: Robot, checker: ValidityChecker, quat: np.ndarray, roles: dict[str, float], jitter: np.ndarray) -> Posture:
    """A posture resting on the ground (lowest point GROUND_GAP_M above z = 0); joints not named by a role at zero."""
    if robot.roles is None:
        raise ValueError(f"robot {robot.name} has no joint roles ([roles] in robot.toml)")
    q = np.zeros(robot.n_joints)
    for name, v in robot.roles.joint_goals(roles).items():
        q[robot.joint_index(name)] = v
    q = np.clip(q + jitter, robot.joint_lower, robot.joint_upper)
    p = Posture(robot.name, np.array([0.0, 0.0, 0.3]), quat, dict(zip(robot.joint_names, q)))
    z = checker.lowest_point_z(checker.qpos_of(p))
    return p.with_root(root_pos=np.array([0.0, 0.0, 0.3 - z + GROUND_GAP_M]))


def _base_pairs() -> dict[str, tuple[tuple[np.ndarray, dict[str, float]], tuple[np.ndarray, dict[str, float]]]]:
    """Start and goal (orientation, role values: robot_rise.roles) of each kind.

    Written for the OP3-class robot (its joint values of issue 7 converted to roles, to 1e-6 deg).
    """

    def d(deg: float) -> float:
        return math.radians(deg)

    sup = supine_quat_wxyz()
    upright = np.array([1.0, 0.0, 0.0, 0.0])
    arms_common = {"left.shoulder_roll": d(-1.191542), "left.elbow": d(83.854084), "right.shoulder_roll": d(-1.191542), "right.elbow": d(83.854084)}

    def legs(left_over: bool) -> dict[str, float]:
        up, down = ("left", "right") if left_over else ("right", "left")
        # the upper leg flexed 35 deg over the lower one (5 deg), both adducted 0.4 rad
        return {f"{up}.hip_pitch": d(-35.0), f"{down}.hip_pitch": d(-5.0), f"{up}.hip_roll": -0.4, f"{down}.hip_roll": -0.4}

    return {
        "crossed_arms": (
            (sup, {**arms_common, "left.shoulder_pitch": d(-103.281127), "right.shoulder_pitch": d(-73.281127)}),
            (sup, {**arms_common, "left.shoulder_pitch": d(-73.281127), "right.shoulder_pitch": d(-103.281127)}),
        ),
        "crossed_legs": ((sup, legs(True)), (sup, legs(False))),
        "arm_under_back": (
            (sup, {"left.shoulder_pitch": d(91.718873), "left.shoulder_roll": d(3.808458), "left.elbow": d(78.854084), "right.shoulder_roll": d(8.808458)}),
            (
                upright,
                {
                    "left.hip_pitch": d(-90.0),
                    "right.hip_pitch": d(-90.0),
                    "left.shoulder_pitch": d(-28.281127),
                    "right.shoulder_pitch": d(-28.281127),
                    "left.shoulder_roll": d(18.808458),
                    "right.shoulder_roll": d(18.808458),
                    "left.elbow": d(8.854084),
                    "right.elbow": d(8.854084),
                },
            ),
        ),
    }


def straight_motion_is_illegal(checker: ValidityChecker, a: Posture, b: Posture) -> bool:
    """True when the straight (lerp / slerp) motion a -> b is illegal somewhere (5 mm resolution)."""
    return not MotionValidator.for_checker(checker, ENERGY_VERIFY_RESOLUTION_M).qpos_segment_valid(checker.qpos_of(a), checker.qpos_of(b))


def crossed_problems(robot: Robot, checker: ValidityChecker, *, kinds: tuple[str, ...] = PROBLEM_KINDS, n: int = 1, seed: int = 0) -> list[CrossedProblem]:
    """``n`` variants per kind (variant 0 = the base pair), all with legal ends and illegal straight motion.

    Raises:
        ValueError: an unknown kind (lists the known ones).
    """
    pairs = _base_pairs()
    unknown = [k for k in kinds if k not in pairs]
    if unknown:
        raise ValueError(f"unknown problem kinds {unknown}; known: {', '.join(PROBLEM_KINDS)}")
    rng = np.random.default_rng(seed)
    out: list[CrossedProblem] = []
    for kind in kinds:
        (qa, ja), (qb, jb) = pairs[kind]
        found = 0
        for attempt in range(20 * n):
            if found == n:
                break
            jitter = np.zeros(robot.n_joints) if attempt == 0 else rng.uniform(-JITTER_RAD, JITTER_RAD, robot.n_joints)
            a = _posture(robot, checker, qa, ja, jitter)
            b = _posture(robot, checker, qb, jb, jitter)
            if checker.is_valid(a) and checker.is_valid(b) and straight_motion_is_illegal(checker, a, b):
                out.append(CrossedProblem(kind, found, a, b))
                found += 1
        if found < n:
            log.warning("%s: only %d of %d variants have legal ends and an illegal straight motion", kind, found, n)
    return out


# --- the 60 lying postures of paper 000 to their library connecting postures -------------------

LYING60_PER_KIND = {"supine": 20, "prone": 20, "left": 10, "right": 10}  # paper 000 section 5
PROBLEM_SETS = ("crossed", "lying60")


def lying60_problems(robot: Robot, checker: ValidityChecker, *, seed: int = 1, per_kind: dict[str, int] | None = None) -> list[CrossedProblem]:
    """Settled lying postures (fixed seed) to their library connecting postures, placed where the robot lies.

    ``kind`` of each problem is its lying kind (supine, prone, left, right); ``variant`` its
    number within the kind. The goal is what ``robot-rise rise`` plans to: the nearest frame
    (K-means tree, paper 000 eq. 1) among the library's lying frames, turned to the start's facing
    and put on the ground at the start's position (``connecting_posture``). When that placed
    posture is itself illegal (e.g. a library frame slightly outside a joint limit), no planner
    can reach it; ``rise`` then moves on to its next candidate, and so do we (nearest legal one of
    the ``DEFAULT_CANDIDATES`` candidates; each problem's ``goal_rank`` and ``goal_frame`` record which).
    """
    from robot_rise.library import connecting_posture, connection_candidates
    from robot_rise.rise import DEFAULT_CANDIDATES, RiseContext
    from robot_rise.sampling import sample_lying

    ctx = RiseContext.build(robot, "flat")
    out: list[CrossedProblem] = []
    for kind, n in (per_kind or LYING60_PER_KIND).items():
        for i, start in enumerate(sample_lying(robot, kind, n, seed).postures):  # type: ignore[arg-type]
            goals = []
            for rank, conn in enumerate(connection_candidates(ctx.library, robot, start, DEFAULT_CANDIDATES, index=ctx.index, tree=ctx.tree)):
                goal = connecting_posture(ctx.library, robot, conn, start, checker)
                goals.append((rank, conn, goal))
                if checker.is_valid(goal):
                    break
            rank, conn, goal = goals[-1]
            if rank:
                log.warning("lying60 %s/%d: nearest library frame(s) illegal when placed; using candidate %d (%s@%d)", kind, i, rank, conn.motion, conn.frame)
            out.append(CrossedProblem(kind, i, start, goal, rank, f"{conn.motion}@{conn.frame}"))
    return out


def library_digest(robot: Robot) -> str:
    """SHA-256 (first 16 hex digits) of the robot's motion library files: the connecting postures depend on them."""
    import hashlib

    from robot_rise.library import robot_library_dir

    h = hashlib.sha256()
    root = robot_library_dir(robot)
    for f in sorted(root.glob("*.json")):
        h.update(f.name.encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:16]


def cached_lying60(robot: Robot, checker: ValidityChecker, seed: int, per_kind: dict[str, int] | None, cache: str | None) -> list[CrossedProblem]:
    """``lying60_problems``, frozen in a JSON file (settling takes minutes; the library may change).

    The file is reused as long as it was made with the same seed and counts, whatever the library
    is now (its digest and the goals' library frames are stored in it); delete it to resample.
    A file from before the ``format`` string (``LYING_PROBLEMS_FORMAT``) is read with a warning:
    its layout is the same, and sampling again takes minutes.

    Raises:
        FormatError: the file is not JSON, has another ``format`` or lacks a field.
    """
    from robot_rise.posture import posture_from_dict, posture_to_dict

    key = {"seed": seed, "per_kind": per_kind or LYING60_PER_KIND}
    if cache and Path(cache).exists():
        data = _read_json(cache, LYING_PROBLEMS_FORMAT, missing_ok=True, fields=("key", "problems"))
        if data.get("key") == key:
            log.warning("lying60 problems from %s (library digest %s; now %s)", cache, data.get("library_digest"), library_digest(robot))
            out = []
            for k, d in enumerate(data["problems"]):
                lacking = [f for f in ("kind", "variant", "start", "goal") if not isinstance(d, dict) or f not in d]
                if lacking:
                    raise FormatError(f"{cache}: problem {k} lacks {', '.join(lacking)}", hint="delete the file to sample the problems again")
                where = f"{cache}: problem {k}"
                out.append(CrossedProblem(d["kind"], d["variant"], posture_from_dict(d["start"], where=f"{where} start"),
                                          posture_from_dict(d["goal"], where=f"{where} goal"), d.get("goal_rank", 0), d.get("goal_frame", "")))
            return out
        log.warning("%s holds other lying problems (%s); sampling again", cache, data.get("key"))
    digest = library_digest(robot)
    out = lying60_problems(robot, checker, seed=seed, per_kind=per_kind)
    if cache:
        Path(cache).parent.mkdir(parents=True, exist_ok=True)
        rows = [
            {"kind": p.kind, "variant": p.variant, "goal_rank": p.goal_rank, "goal_frame": p.goal_frame,
             "start": posture_to_dict(p.start), "goal": posture_to_dict(p.goal)}
            for p in out
        ]
        Path(cache).write_text(json.dumps({"format": LYING_PROBLEMS_FORMAT, "key": key, "library_digest": digest, "problems": rows}))
    return out


def _read_json(path: str, expected: str, *, missing_ok: bool = False, fields: tuple[str, ...] = ()) -> dict:
    """The JSON object of ``path``, checked to be of format ``expected`` and to have ``fields``.

    ``missing_ok``: a file without any ``format`` (written before this version string) is read
    with a warning instead of refused.

    Raises:
        RobotRiseError: the file cannot be read.
        FormatError: not a JSON object, another (or, unless ``missing_ok``, no) ``format``, or a field missing.
    """
    try:
        text = Path(path).read_text()
    except OSError as e:
        raise RobotRiseError(f"{path}: cannot be read ({e.strerror})", hint="check the path") from e
    try:
        data = json.loads(text)
    except json.JSONDecodeError as e:
        raise FormatError(f"{path}: not a JSON file ({e})", hint=f"expected a {expected!r} file") from e
    if not isinstance(data, dict):
        raise FormatError(f"{path}: not a JSON object", hint=f"expected a {expected!r} file")
    got = data.get("format")
    if got is None and missing_ok:
        log.warning("%s has no format string; read as %s (its layout)", path, expected)
    elif got != expected:
        raise FormatError(f"{path}: format is {got!r}, expected {expected!r}",
                          hint="pass a file this benchmark wrote (re-run it with --out), or add the format field if the file is from before it")
    lacking = [f for f in fields if f not in data]
    if lacking:
        raise FormatError(f"{path}: no {', '.join(lacking)} field in this {expected!r} file", hint="pass a file this benchmark wrote")
    return data


# --- measurement ----------------------------------------------------------------------------------


def dimensionless_jerk(t: np.ndarray, q: np.ndarray) -> float:
    """Integrated squared jerk times D^5 / A^2 (Hogan & Sternad 2009): duration D [s], joint-space path length A [rad].

    Scale-free: the same path shape played slower or scaled in amplitude gives the same value, so
    long slow paths and short quick ones compare on shape and timing profile alone.
    """
    if len(t) < 4:
        return 0.0
    amp = float(np.sum(np.linalg.norm(np.diff(q, axis=0), axis=1)))
    dur = float(t[-1] - t[0])
    return integrated_squared_jerk(t, q) * dur**5 / max(amp, 1e-9) ** 2


def common_duration_jerk(jerk: float, duration_s: float, reference_s: float) -> float:
    """Integrated squared jerk of the same motion played uniformly slower or faster, in ``reference_s`` [rad^2/s^5].

    Playing q(t) as q(t D / D_ref) multiplies the third derivative by (D / D_ref)^3 and the
    integration interval by D_ref / D, so the integral scales exactly by (D / D_ref)^5. The raw
    integral therefore ranks a path partly by how slowly it is timed (a path timed twice as long
    has 1/32 of the jerk); at a common duration the paths compare on shape and timing profile,
    while amplitude (a longer path needs more jerk in the same time) still counts, unlike the
    dimensionless jerk.
    """
    if not (duration_s > 0 and reference_s > 0):
        return math.nan
    return jerk * (duration_s / reference_s) ** 5


def root_motion(root: np.ndarray | None) -> tuple[float, float]:
    """Travel [m] of the root position and total rotation [rad] of its orientation along rows (T, 7); NaN without rows."""
    if root is None or len(root) < 2:
        return math.nan, math.nan
    from robot_rise.planning.space import quat_angle

    travel = float(np.sum(np.linalg.norm(np.diff(root[:, :3], axis=0), axis=1)))
    rot = float(np.sum(2.0 * quat_angle(root[:-1, 3:7], root[1:, 3:7])))
    return travel, rot


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


def with_common_duration_jerk(rows: list[BenchRow], reference: tuple[str, ...] = THREE) -> list[BenchRow]:
    """Rows with ``jerk_common_duration``: each problem's jerks at the longest duration of the ``reference`` planners on it.

    The reference duration of a problem is the longest timed duration among the rows of the
    ``reference`` planners that solved it (all rows when none of them is present); unsolved rows
    keep NaN.
    """
    ref: dict[tuple[str, str, int], float] = {}
    have_ref = any(r.planner in reference for r in rows)
    for r in rows:
        if r.solved and (r.planner in reference or not have_ref):
            k = (r.pset, r.kind, r.variant)
            ref[k] = max(ref.get(k, 0.0), r.duration_s)
    out = []
    for r in rows:
        k = (r.pset, r.kind, r.variant)
        val = common_duration_jerk(r.jerk, r.duration_s, ref[k]) if r.solved and k in ref else math.nan
        out.append(dataclasses.replace(r, jerk_common_duration=val))
    return out


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
        problems += [("lying60", p) for p in cached_lying60(robot, checker, lying_seed, lying_per_kind, lying_cache)]
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


def _groups(rows: list[BenchRow]) -> list[tuple[str, str, list[BenchRow]]]:
    """(planner, problem label, rows): crossed kinds one by one, lying60 as one set."""
    keys: list[tuple[str, str]] = []
    for r in rows:
        k = (r.planner, r.kind if r.pset == "crossed" else r.pset)
        if k not in keys:
            keys.append(k)
    return [(p, lab, [r for r in rows if r.planner == p and (r.kind if r.pset == "crossed" else r.pset) == lab]) for p, lab in keys]


def summary_table(rows: list[BenchRow]) -> str:
    """Markdown table per problem set and planner: success, times, length, clearance, jerks, duration, root motion."""
    rows = with_common_duration_jerk(rows)
    lines = [
        "| problem | planner | success | plan time median / p95 [s] | total time median / p95 [s] | path length median | "
        "min self / ground clearance [mm] | integrated sq. jerk median [rad²/s⁵] | jerk at common duration median [rad²/s⁵] | "
        "dimensionless jerk median | duration median [s] | root travel / rotation median [m / rad] |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    groups = _groups(rows)
    order = {lab: k for k, lab in enumerate(dict.fromkeys(lab for _, lab, _ in groups))}
    pl = {p: k for k, p in enumerate(PLANNER_NAMES)}
    for planner, label, rs in sorted(groups, key=lambda g: (order[g[1]], pl.get(g[0], 99))):
        ok = [r for r in rs if r.solved]

        def med(vals: list[float]) -> str:
            return f"{np.median(vals):.3g}" if vals else "-"

        def mp(vals: list[float]) -> str:
            return f"{np.median(vals):.2f} / {np.percentile(vals, 95):.2f}" if vals else "-"

        clear = f"{1000 * min(r.min_self_clearance_m for r in ok):.1f} / {1000 * min(r.min_ground_clearance_m for r in ok):.1f}" if ok else "-"
        lines.append(
            f"| {label} | {planner} | {len(ok)}/{len(rs)} ({100 * len(ok) / max(1, len(rs)):.0f} %) | {mp([r.plan_s for r in ok])} | "
            f"{mp([r.total_s for r in ok])} | {med([r.path_length for r in ok])} | {clear} | {med([r.jerk for r in ok])} | "
            f"{med([r.jerk_common_duration for r in ok if not math.isnan(r.jerk_common_duration)])} | "
            f"{med([r.dimensionless_jerk for r in ok if not math.isnan(r.dimensionless_jerk)])} | {med([r.duration_s for r in ok])} | "
            f"{med([r.root_travel_m for r in ok if not math.isnan(r.root_travel_m)])} / "
            f"{med([r.root_rotation_rad for r in ok if not math.isnan(r.root_rotation_rad)])} |"
        )
    return "\n".join(lines)


def paired_jerk_table(rows: list[BenchRow], measure: str = "jerk") -> str:
    """Per problem label: on how many problems solved by all planners each planner had the lowest ``measure``.

    A planner counts a problem only when it is strictly lowest there; equal lowest values (e.g. two
    planners returning the same straight motion) are counted in the ``tied`` column, not given to
    the first planner. ``jerk_common_duration`` must already be filled (``with_common_duration_jerk``)
    to rank by it.
    """
    names = list(dict.fromkeys(r.planner for r in rows))
    lines = ["| problem | solved by all | " + " | ".join(f"{n} lowest {measure.replace('_', ' ')}" for n in names) + " | tied |",
             "| --- | --- |" + " --- |" * (len(names) + 1)]
    labels = list(dict.fromkeys(r.kind if r.pset == "crossed" else r.pset for r in rows))
    for lab in labels:
        by: dict[tuple[str, int], dict[str, BenchRow]] = {}
        for r in rows:
            if (r.kind if r.pset == "crossed" else r.pset) == lab:
                by.setdefault((r.kind, r.variant), {})[r.planner] = r
        common = [v for v in by.values() if len(v) == len(names) and all(x.solved for x in v.values())]
        wins = dict.fromkeys(names, 0)
        tied = 0
        for v in common:
            low = min(getattr(x, measure) for x in v.values())
            best = [n for n, x in v.items() if getattr(x, measure) <= low]
            if len(best) == 1:
                wins[best[0]] += 1
            else:
                tied += 1
        lines.append(f"| {lab} | {len(common)} | " + " | ".join(str(wins[n]) for n in names) + f" | {tied} |")
    return "\n".join(lines)


def load_rows(paths: list[str]) -> list[BenchRow]:
    """The runs of saved ``--out`` files (``BENCH_ENERGY_FORMAT``).

    Raises:
        FormatError: a file of another format, or a run with missing or unknown fields.
    """
    names = {f.name for f in dataclasses.fields(BenchRow)}
    required = {f.name for f in dataclasses.fields(BenchRow) if f.default is dataclasses.MISSING}
    rows: list[BenchRow] = []
    for p in paths:
        for k, r in enumerate(_read_json(p, BENCH_ENERGY_FORMAT, fields=("runs",))["runs"]):
            if not isinstance(r, dict):
                raise FormatError(f"{p}: run {k} is not an object", hint="pass a file this benchmark wrote with --out")
            missing, unknown = sorted(required - set(r)), sorted(set(r) - names)
            wrong = ([f"lacks {', '.join(missing)}"] if missing else []) + ([f"has unknown fields {', '.join(unknown)}"] if unknown else [])
            if wrong:
                raise FormatError(f"{p}: run {k} " + "; ".join(wrong), hint=f"a run has the fields {', '.join(sorted(names))}")
            rows.append(BenchRow(**r))
    return rows


def _print(rows: list[BenchRow]) -> None:
    print(summary_table(rows))
    print()
    three = with_common_duration_jerk([r for r in rows if r.planner in THREE])  # the paired counts compare the three planners
    for measure in ("jerk", "jerk_common_duration", "dimensionless_jerk"):
        print(paired_jerk_table(three, measure))
        print()
    for abl in ABLATIONS:  # each ablation in place of the energy planner (RRT-blossom's in its place)
        if any(r.planner == abl for r in rows):
            trio = (("energy_oldsmooth" if abl.endswith("oldsmooth") else "energy_abc"), abl, "ompl_rrtconnect") if abl.startswith("rrt_blossom") else (abl, "rrt_blossom", "ompl_rrtconnect")
            if not all(any(r.planner == n for r in rows) for n in trio):
                continue
            alt = with_common_duration_jerk([r for r in rows if r.planner in trio], reference=trio)
            for measure in ("jerk", "jerk_common_duration", "dimensionless_jerk"):
                print(paired_jerk_table(alt, measure))
                print()
    for r in rows:
        if not r.solved:
            print(f"- {r.planner} {r.pset} {r.kind}/{r.variant}: {r.reason[:300]}")


def main(argv: list[str] | None = None) -> int:
    """Command line: run the benchmark (or merge saved runs) and print the Markdown tables and failures."""
    ap = argparse.ArgumentParser(description="Energy planner benchmark (paper 004) beside RRT-blossom and OMPL RRT-Connect.")
    ap.add_argument("--sets", nargs="*", default=["crossed"], choices=PROBLEM_SETS, help="problem sets")
    ap.add_argument("--n", type=int, default=5, help="variants per crossed-limb kind")
    ap.add_argument("--budget", type=float, default=30.0, help="planning budget per run [s]")
    ap.add_argument("--seed", type=int, default=0, help="crossed-limb jitter seed and planner seed base")
    ap.add_argument("--lying-seed", type=int, default=1, help="sampling seed of the 60 lying postures")
    ap.add_argument("--planners", nargs="*", default=None, help=f"prefixes of {', '.join(PLANNER_NAMES)}")
    ap.add_argument("--kinds", nargs="*", default=list(PROBLEM_KINDS), choices=PROBLEM_KINDS)
    ap.add_argument("--out", default=None, help="write every run (and the arguments) as JSON here")
    ap.add_argument("--merge", nargs="*", default=None, help="print the tables of saved --out files instead of running")
    ap.add_argument("--lying-cache", default=None, help="keep the sampled lying60 problems in this JSON file (reused when it matches)")
    ap.add_argument("-v", "--verbose", action="store_true")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        return _run(args)
    except RobotRiseError as e:  # a bad input file: one line and a hint, no traceback
        print(f"error: {e}", file=sys.stderr)
        if e.hint:
            print(f"hint: {e.hint}", file=sys.stderr)
        return 2


def _run(args: argparse.Namespace) -> int:
    if args.merge:
        _print(load_rows(args.merge))
        return 0
    t0 = time.monotonic()
    done: list[BenchRow] = []

    def save(row: BenchRow | None = None) -> None:  # after every run, so that a long run keeps what it measured
        if row is not None:
            done.append(row)
        if args.out:
            Path(args.out).parent.mkdir(parents=True, exist_ok=True)
            Path(args.out).write_text(json.dumps({"format": BENCH_ENERGY_FORMAT, "args": vars(args), "wall_s": time.monotonic() - t0,
                                                  "runs": [asdict(r) for r in done]}, indent=1))

    rows = run_benchmark(sets=tuple(args.sets), n=args.n, budget_s=args.budget, seed=args.seed, lying_seed=args.lying_seed,
                         planners=args.planners, kinds=tuple(args.kinds), progress=save,
                         lying_cache=args.lying_cache)
    save()
    _print(rows)
    print(f"\nwall {time.monotonic() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
