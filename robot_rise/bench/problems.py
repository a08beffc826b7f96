"""Planning problems for tests and benchmarks: lying postures to connecting postures.

The issue-5 benchmark runs on a FROZEN problem set (``configs/bench/planning_problems.json``,
format ``robot-rise/planning-problems@1``, made by :func:`build_problem_set`): the 60 settled
lying postures of paper 000's protocol (seed 1: 20 supine, 20 prone, 10 left, 10 right) to the
connecting posture ``robot-rise rise`` selects for each (library selection, below), and the
beam, low-bed and table scenes, each with two problems: its lying posture to the library
connecting posture selected in that scene, and to the crouch beyond the obstacle; and a stress
set ``turnover60``: the same 60 postures to the connecting postures of the prone-only library of
commit 8e60c43 (supine and lateral starts must turn over). The motion library changes; the
frozen file keeps the benchmark's problems fixed (its digest is stored).

Library selection (what ``robot_rise.rise`` does, :func:`library_connecting_posture`): the
nearest frames of the ``DEFAULT_CANDIDATES`` nearest motions among the library's lying frames
(``RiseContext``, K-means tree, paper 000 eq. 1), each placed where the robot lies
(``connecting_posture``); the first whose placement is legal is the goal.

The lying postures come from :func:`robot_rise.sampling.sample_lying` (settled in
MuJoCo, fixed seeds: the paper 000 section 5 protocol of 20 supine, 20 prone, 20 lateral).
Connecting postures come from the motion library when ``robot_rise.library`` offers a selection
function; until then from :func:`fallback_connecting_posture`, a deep crouch on both feet made
from the robot's ``stand`` keyframe (the posture the OP3 get-up motions pass through before
standing). Either way the goal is aligned to the start in yaw and ground position (paper 000
section 4.1: "the global position and facing direction ... are roughly aligned").
"""

from __future__ import annotations

import json
import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from robot_rise.model import Robot
from robot_rise.placement import align_to_start
from robot_rise.fileio import write_text_atomic
from robot_rise.library import library_digest
from robot_rise.paths import configs_dir
from robot_rise.posture import Posture, posture_from_dict, posture_to_dict, quat_multiply
from robot_rise.validity import ValidityChecker

__all__ = [
    "fallback_connecting_posture",
    "align_to_start",
    "connecting_posture_for",
    "BenchProblem",
    "lying_problems",
    "obstacle_problems",
    "CROUCH_LEG_SCALE",
    "PROBLEMS_FORMAT",
    "DEFAULT_PROBLEMS_FILE",
    "FLAT60_PER_KIND",
    "FrozenProblem",
    "library_connecting_posture",
    "build_problem_set",
    "save_problem_set",
    "load_problem_set",
]

log = logging.getLogger(__name__)

CROUCH_LEG_SCALE = 3.0  # leg joints of the stand keyframe times this: a deep, balanced crouch


def fallback_connecting_posture(robot: Robot) -> Posture:
    """A deep crouch on both feet: the stand keyframe with every leg joint scaled (clipped to limits).

    Root at the origin, upright; ``align_to_start`` places it. Limbs named ``*leg*`` in robot.toml.
    """
    q = np.array(robot.stand_qpos[7:], dtype=float)
    legs = {j for name, joints in robot.limbs.items() if "leg" in name for j in joints}
    for i, name in enumerate(robot.joint_names):
        if name in legs:
            q[i] *= CROUCH_LEG_SCALE
    q = np.clip(q, robot.joint_lower, robot.joint_upper)
    return Posture(robot.name, np.zeros(3), robot.stand_qpos[3:7], dict(zip(robot.joint_names, q)))


def connecting_posture_for(start: Posture, checker: ValidityChecker) -> Posture:
    """Connecting posture for a lying posture: library selection (the one ``rise`` uses); the
    fallback crouch for a robot without a motion library."""
    from robot_rise.errors import FormatError
    from robot_rise.library import select_connecting_posture

    try:
        return select_connecting_posture(start, checker.robot)
    except FormatError as e:  # no library for this robot
        log.warning("library selection failed (%s); using the fallback crouch", e)
    return align_to_start(fallback_connecting_posture(checker.robot), start, checker)


PROBLEMS_FORMAT = "robot-rise/planning-problems@1"
DEFAULT_PROBLEMS_FILE = "bench/planning_problems.json"  # under configs_dir()
FLAT60_PER_KIND = {"supine": 20, "prone": 20, "left": 10, "right": 10}  # paper 000 section 5 protocol


@dataclass(frozen=True)
class BenchProblem:
    """One benchmark problem: name, scene, start and goal postures."""

    name: str
    scene: str
    start: Posture
    goal: Posture
    key: Posture | None = None


def lying_problems(robot: Robot, n_per_kind: int, seed: int, *, kinds: tuple[str, ...] = ("supine", "prone", "left", "right"), per_kind: dict[str, int] | None = None) -> list[BenchProblem]:
    """Flat-ground problems from settled lying postures to their connecting postures.

    Args:
        n_per_kind: postures per kind (``per_kind`` overrides per kind, e.g. lateral 10 + 10).
        seed: sampling seed (each kind uses it).
    """
    from robot_rise.sampling import sample_lying

    checker = ValidityChecker(robot, "flat")
    out: list[BenchProblem] = []
    for kind in kinds:
        n = (per_kind or {}).get(kind, n_per_kind)
        if n <= 0:
            continue
        res = sample_lying(robot, kind, n, seed)  # type: ignore[arg-type]
        for i, p in enumerate(res.postures):
            out.append(BenchProblem(f"{kind}_{seed}_{i:03d}", "flat", p, connecting_posture_for(p, checker)))
    return out


def obstacle_problems(robot: Robot) -> list[BenchProblem]:
    """The beam, low-bed and table scenes of paper 000 section 5.2 with fixed lying postures.

    beam: prone, head toward +x, face next to the beam; goal crouch on the robot's spot.
    low_bed: supine on the bed, legs over its -x edge; goal crouch on the floor beside the bed.
    table: supine with the trunk under the table, head in, feet out; goal crouch in the open
    beyond its edge, where the feet were (the robot must slide out before rising).
    """
    crouch = fallback_connecting_posture(robot)
    out: list[BenchProblem] = []
    specs = [
        # scene, kind, root xy of the lying robot, root yaw [rad], goal xy
        ("beam", "prone", (-0.02, 0.0), 0.0, (-0.05, 0.0)),
        ("low_bed", "supine", (0.15, 0.0), math.pi, (-0.25, 0.0)),
        ("table", "supine", (0.0, 0.12), math.pi / 2, (0.0, 0.45)),
    ]
    for scene, kind, xy, yaw, goal_xy in specs:
        checker = ValidityChecker(robot, scene)
        start = lying_posture_at(robot, checker, kind, xy, yaw)
        goal = align_to_start(crouch, start, checker, xy=np.asarray(goal_xy))
        if scene == "low_bed":
            goal = goal  # the floor: lowest point at z = 0
        out.append(BenchProblem(f"{scene}_{kind}", scene, start, goal))
    return out


def lying_posture_at(robot: Robot, checker: ValidityChecker, kind: str, xy: tuple[float, float], yaw: float) -> Posture:
    """A straight lying posture (stand joints, arms by the side) resting on whatever is below.

    The root height is found by lowering the robot until just before it becomes invalid.
    """
    nominal = {
        "supine": np.array([math.cos(-math.pi / 4), 0.0, math.sin(-math.pi / 4), 0.0]),
        "prone": np.array([math.cos(math.pi / 4), 0.0, math.sin(math.pi / 4), 0.0]),
    }[kind]
    rz = np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])
    quat = quat_multiply(rz, nominal)
    joints = dict(zip(robot.joint_names, robot.stand_qpos[7:]))
    p = Posture(robot.name, np.array([xy[0], xy[1], 0.5]), quat, joints)
    lo, hi = -0.1, 0.5
    for _ in range(40):  # bisection on root height: highest invalid / lowest valid
        mid = 0.5 * (lo + hi)
        if checker.is_valid(p.with_root(np.array([xy[0], xy[1], mid]))):
            hi = mid
        else:
            lo = mid
    return p.with_root(np.array([xy[0], xy[1], hi + checker.contact_tolerance_m]))


# --- the frozen issue-5 problem set --------------------------------------------------------------


@dataclass(frozen=True)
class FrozenProblem:
    """One problem of the frozen benchmark set.

    Attributes:
        name: unique, e.g. ``supine/3`` or ``beam/library``.
        pset: problem set (``flat60``, ``beam``, ``low_bed``, ``table``).
        scene: scene name for ``ValidityChecker``.
        start, goal: postures.
        goal_source: where the goal came from: ``library motion@frame (candidate r)`` or ``crouch``.
    """

    name: str
    pset: str
    scene: str
    start: Posture
    goal: Posture
    goal_source: str


def library_connecting_posture(ctx: Any, start: Posture) -> tuple[Posture, str]:
    """The connecting posture ``rise`` plans to first (``problem.select_goal``): (goal, ``"library motion@frame (candidate r)"``)."""
    from robot_rise.rise import select_goal  # a benchmark of rise's problems: the planner itself never imports rise

    sel = select_goal(ctx, start)
    return sel.goal, f"library {sel.source}"


def build_problem_set(
    robot: Robot, *, seed: int = 1, per_kind: dict[str, int] | None = None, turnover_library: str | os.PathLike[str] | None = None
) -> list[FrozenProblem]:
    """Sample and select the issue-5 problems (minutes: settling the lying postures in MuJoCo).

    Args:
        seed: sampling seed of the lying postures (each kind uses it; paper protocol: 1).
        per_kind: lying postures per kind (default FLAT60_PER_KIND).
        turnover_library: optional motion-library directory with prone motions only (the one
            of commit 8e60c43: ``git archive 8e60c43 configs/motions/op3 | tar -x -C DIR``): the
            same 60 lying postures to ITS connecting postures make the ``turnover60`` stress
            set, where supine and lateral starts must turn over.
    """
    from robot_rise.library import load_library
    from robot_rise.rise import RiseContext
    from robot_rise.sampling import sample_lying

    out: list[FrozenProblem] = []
    ctx = RiseContext.build(robot, "flat")
    tctx = RiseContext.build(robot, "flat", library=load_library(turnover_library)) if turnover_library is not None else None
    turnover: list[FrozenProblem] = []
    for kind, n in (per_kind or FLAT60_PER_KIND).items():
        for i, start in enumerate(sample_lying(robot, kind, n, seed).postures):  # type: ignore[arg-type]
            goal, source = library_connecting_posture(ctx, start)
            out.append(FrozenProblem(f"{kind}/{i}", "flat60", "flat", start, goal, source))
            log.info("flat60 %s/%d -> %s", kind, i, source)
            if tctx is not None:
                goal, source = library_connecting_posture(tctx, start)
                turnover.append(FrozenProblem(f"turnover/{kind}/{i}", "turnover60", "flat", start, goal, f"{source} of {turnover_library}"))
    out += turnover
    for crouch in obstacle_problems(robot):
        sctx = RiseContext.build(robot, crouch.scene, library=ctx.library)
        goal, source = library_connecting_posture(sctx, crouch.start)
        out.append(FrozenProblem(f"{crouch.scene}/library", crouch.scene, crouch.scene, crouch.start, goal, source))
        out.append(FrozenProblem(f"{crouch.scene}/crouch", crouch.scene, crouch.scene, crouch.start, crouch.goal, "crouch"))
    return out


def _resolve(path: str | os.PathLike[str] | None) -> Path:
    return configs_dir() / DEFAULT_PROBLEMS_FILE if path is None else Path(path)


def save_problem_set(problems: list[FrozenProblem], robot: Robot, path: str | os.PathLike[str] | None = None, *, seed: int = 1) -> Path:
    """Write the problems as ``robot-rise/planning-problems@1`` JSON (atomically)."""
    p = _resolve(path)
    doc = {
        "format": PROBLEMS_FORMAT,
        "robot": robot.name,
        "seed": seed,
        "library_digest": library_digest(robot),
        "note": "issue-5 benchmark problems, frozen; regenerate with robot-rise bench planning --regenerate",
        "problems": [
            {"name": q.name, "set": q.pset, "scene": q.scene, "goal_source": q.goal_source,
             "start": posture_to_dict(q.start), "goal": posture_to_dict(q.goal)}
            for q in problems
        ],
    }
    p.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(p, json.dumps(doc, indent=1) + "\n")
    return p


def load_problem_set(robot: Robot, path: str | os.PathLike[str] | None = None) -> list[FrozenProblem]:
    """Read a frozen problem set (default DEFAULT_PROBLEMS_FILE).

    Raises:
        ValueError: wrong ``format`` or robot.
    """
    p = _resolve(path)
    doc = json.loads(p.read_text())
    if doc.get("format") != PROBLEMS_FORMAT:
        raise ValueError(f"{p}: format is {doc.get('format')!r}, expected {PROBLEMS_FORMAT!r}")
    if doc.get("robot") != robot.name:
        raise ValueError(f"{p}: problems for robot {doc.get('robot')!r}, not {robot.name!r}")
    return [
        FrozenProblem(d["name"], d["set"], d["scene"], posture_from_dict(d["start"], robot, where=f"{p}: {d['name']} start"),
                      posture_from_dict(d["goal"], robot, where=f"{p}: {d['name']} goal"), d["goal_source"])
        for d in doc["problems"]
    ]
