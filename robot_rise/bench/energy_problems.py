"""Problems of the energy-planner benchmark (issue 7): crossed limbs, and the 60 lying postures.

Problem sets (:data:`PROBLEM_SETS`):

- crossed-limb problems, where the straight interpolation penetrates (issue 7, "Measured"):

  - ``crossed_arms``: lying supine, forearms folded across the chest, left over right -> right over left;
  - ``crossed_legs``: lying supine, legs crossed with the left over the right -> the right over the left;
  - ``arm_under_back``: supine with the left arm under the back -> a sitting posture (torso upright,
    hips flexed 90 degrees, legs straight on the ground, hands forward).

  Each kind has ``n`` variants: the base pair with seeded joint jitter (the same jitter on both
  ends), kept only when both ends are legal and the straight motion between them is not.

- ``lying60``: the paper 000 section 5 protocol, 60 settled lying postures on flat ground
  (``sample_lying``, fixed seed: 20 supine, 20 prone, 10 left, 10 right) to their LIBRARY
  connecting postures, exactly as ``robot-rise rise`` selects them (``robot_rise.rise.select_goal``).

File: ``--lying-cache`` freezes the sampled lying60 problems (``"robot-rise/lying-problems@1"``;
a cache from before that string is read with a warning).
"""

from __future__ import annotations

import json
import logging
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robot_rise.constants import ENERGY_VERIFY_RESOLUTION_M
from robot_rise.errors import FormatError, RobotRiseError
from robot_rise.library import library_digest
from robot_rise.model import Robot
from robot_rise.planning.motion_validator import MotionValidator
from robot_rise.posture import Posture
from robot_rise.validity import ValidityChecker

__all__ = [
    "LYING_PROBLEMS_FORMAT",
    "CrossedProblem",
    "PROBLEM_KINDS",
    "PROBLEM_SETS",
    "LYING60_PER_KIND",
    "supine_quat_wxyz",
    "crossed_problems",
    "straight_motion_is_illegal",
    "lying60_problems",
    "cached_lying60",
    "read_bench_file",
]

log = logging.getLogger(__name__)

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


def lying60_problems(robot: Robot, *, seed: int = 1, per_kind: dict[str, int] | None = None) -> list[CrossedProblem]:
    """Settled lying postures (fixed seed) to their library connecting postures, placed where the robot lies.

    ``kind`` of each problem is its lying kind (supine, prone, left, right); ``variant`` its
    number within the kind. The goal is what ``robot-rise rise`` plans to
    (``robot_rise.rise.select_goal`` on flat ground): the nearest frame (K-means tree, paper 000
    eq. 1) among the library's lying frames, turned to the start's facing and put on the ground
    at the start's position; when that placed posture is itself illegal (e.g. a library frame
    slightly outside a joint limit), the next of the ``DEFAULT_CANDIDATES`` candidates, as
    ``rise`` moves on (each problem's ``goal_rank`` and ``goal_frame`` record which); when none
    is legal, the nearest (``select_goal``: the planner then says why it is invalid).
    """
    from robot_rise.rise import RiseContext, select_goal
    from robot_rise.sampling import sample_lying

    ctx = RiseContext.build(robot, "flat")
    out: list[CrossedProblem] = []
    for kind, n in (per_kind or LYING60_PER_KIND).items():
        for i, start in enumerate(sample_lying(robot, kind, n, seed).postures):  # type: ignore[arg-type]
            sel = select_goal(ctx, start)
            frame, rank = _frame_and_rank(sel.source)
            if rank:
                log.warning("lying60 %s/%d: nearest library frame(s) illegal when placed; using candidate %d (%s)", kind, i, rank, frame)
            elif not ctx.checker.is_valid(sel.goal):
                log.warning("lying60 %s/%d: no candidate is legal when placed; the nearest (%s), which no planner reaches", kind, i, frame)
            out.append(CrossedProblem(kind, i, start, sel.goal, rank, frame))
    return out


_SOURCE = re.compile(r"(?P<frame>\S+@\d+) \(candidate (?P<rank>\d+)\)")  # GoalSelection.source


def _frame_and_rank(source: str) -> tuple[str, int]:
    """``motion@frame`` and the candidate number of a ``GoalSelection.source`` (its only record of them)."""
    m = _SOURCE.fullmatch(source)
    if m is None:
        raise RobotRiseError(f"goal selection source {source!r} is not 'motion@frame (candidate r)'")
    return m["frame"], int(m["rank"])


def cached_lying60(robot: Robot, seed: int, per_kind: dict[str, int] | None, cache: str | None) -> list[CrossedProblem]:
    """``lying60_problems``, frozen in a JSON file (settling takes minutes; the library may change).

    The file is reused as long as it was made with the same seed and counts, whatever the library
    is now (its digest, :func:`robot_rise.library.library_digest`, and the goals' library frames
    are stored in it); delete it to resample. A file from before the ``format`` string
    (``LYING_PROBLEMS_FORMAT``) is read with a warning: its layout is the same, and sampling again
    takes minutes.

    Raises:
        FormatError: the file is not JSON, has another ``format`` or lacks a field.
    """
    from robot_rise.posture import posture_from_dict, posture_to_dict

    key = {"seed": seed, "per_kind": per_kind or LYING60_PER_KIND}
    if cache and Path(cache).exists():
        data = read_bench_file(cache, LYING_PROBLEMS_FORMAT, missing_ok=True, fields=("key", "problems"))
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
    out = lying60_problems(robot, seed=seed, per_kind=per_kind)
    if cache:
        Path(cache).parent.mkdir(parents=True, exist_ok=True)
        rows = [
            {"kind": p.kind, "variant": p.variant, "goal_rank": p.goal_rank, "goal_frame": p.goal_frame,
             "start": posture_to_dict(p.start), "goal": posture_to_dict(p.goal)}
            for p in out
        ]
        Path(cache).write_text(json.dumps({"format": LYING_PROBLEMS_FORMAT, "key": key, "library_digest": digest, "problems": rows}))
    return out


def read_bench_file(path: str, expected: str, *, missing_ok: bool = False, fields: tuple[str, ...] = ()) -> dict:
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
