"""Planning problems for tests and benchmarks: lying postures to connecting postures.

The lying postures come from :func:`robot_rise.sampling.sample_lying_postures` (settled in
MuJoCo, fixed seeds: the paper 000 section 5 protocol of 20 supine, 20 prone, 20 lateral).
Connecting postures come from the motion library when ``robot_rise.library`` offers a selection
function; until then from :func:`fallback_connecting_posture`, a deep crouch on both feet made
from the robot's ``stand`` keyframe (the posture the OP3 get-up motions pass through before
standing). Either way the goal is aligned to the start in yaw and ground position (paper 000
section 4.1: "the global position and facing direction ... are roughly aligned").
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from robot_rise.model import Robot
from robot_rise.placement import align_to_start
from robot_rise.posture import Posture, quat_multiply
from robot_rise.validity import ValidityChecker

__all__ = [
    "fallback_connecting_posture",
    "align_to_start",
    "connecting_posture_for",
    "BenchProblem",
    "lying_problems",
    "obstacle_problems",
    "CROUCH_LEG_SCALE",
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
    """Connecting posture for a lying posture: library selection if available, else the fallback crouch."""
    try:  # the motion library (issue: library) may not exist yet
        from robot_rise import library  # type: ignore[attr-defined]

        select = getattr(library, "select_connecting_posture", None)
    except ImportError:
        select = None
    if select is not None:
        try:
            return select(start, checker.robot)
        except Exception as e:  # library under construction: fall back, say so
            log.warning("library selection failed (%s); using the fallback crouch", e)
    return align_to_start(fallback_connecting_posture(checker.robot), start, checker)


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
    from robot_rise.sampling import sample_lying_postures

    checker = ValidityChecker(robot, "flat")
    out: list[BenchProblem] = []
    for kind in kinds:
        n = (per_kind or {}).get(kind, n_per_kind)
        if n <= 0:
            continue
        res = sample_lying_postures(robot, kind, n, seed)  # type: ignore[arg-type]
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
        start = _lying_posture(robot, checker, kind, xy, yaw)
        goal = align_to_start(crouch, start, checker, xy=np.asarray(goal_xy))
        if scene == "low_bed":
            goal = goal  # the floor: lowest point at z = 0
        out.append(BenchProblem(f"{scene}_{kind}", scene, start, goal))
    return out


def _lying_posture(robot: Robot, checker: ValidityChecker, kind: str, xy: tuple[float, float], yaw: float) -> Posture:
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
