"""Connecting-posture selection (paper 000 section 4.1): which library frame a lying robot joins,
and that frame placed where the robot lies. The one pipeline ``rise`` and the benchmarks use.
"""

from __future__ import annotations

import dataclasses
import logging
import os
from functools import lru_cache
from pathlib import Path

import numpy as np

from robot_rise.constants import JOINT_SPEED_FRACTION_OF_NO_LOAD, ROOT_ANGULAR_SPEED_LIMIT_RAD_S
from robot_rise.library.frames import Connection, FrameIndex
from robot_rise.library.motions import MotionLibrary, load_library, robot_library_dir
from robot_rise.library.tree import KMeansTree
from robot_rise.model import Robot
from robot_rise.placement import place_near
from robot_rise.posture import Posture
from robot_rise.validity import ValidityChecker

__all__ = ["LYING_ROOT_RISE_M", "MAX_ROOT_TURN_RAD", "MAX_ROLL_ONTO_FRONT_RAD", "lying_frames", "connection_candidates", "expected_getup_s", "connecting_posture", "select_connecting_posture"]

log = logging.getLogger(__name__)

LYING_ROOT_RISE_M = 0.02  # a library frame counts as lying while its root is this close to the start's height
MAX_ROOT_TURN_RAD = 0.6  # duration ranking: frames whose root is turned further from the start's are out of a plan's reach
# ... except a prone motion's frames, up to this turn: a body on its side rolls onto its front
# (limbs fold forward, gravity does the rest), not off its back. OP3, seed 1: side starts whose
# root is 0.9-1.9 rad from a prone frame were proven joining prone_elbow_knees_quick (5 of 5, its 2.4 s timing then),
# 2.3 rad (a side leaning back) not; from the back onto a side: 0 of 6.
MAX_ROLL_ONTO_FRONT_RAD = 2.0
# Approaches (first command to the connecting frame, as proven) took 1.8-7.9x (median 3.0x) the
# straight-line trapezoid (16 rises, 4 per lying kind, seed 1): the path bends around the body,
# a roll waits for gravity and the filter slows what the servos cannot follow. Timed by path
# length (2026-12-03) they take 1.3-4.5x, median 2.2x (the same 16 but one rise after a fall);
# with 2.2 the 300-posture protocol (2026-12-04) changed only two postures, each to the other
# roll (one 1.18 s sooner, one 0.12 s later), and the median by 6 ms (BENCHMARKS.md, issue 17),
# so the ranking keeps 3.0.
APPROACH_TIME_FACTOR = 3.0


def lying_frames(index: FrameIndex, library: MotionLibrary, *, max_rise_m: float = LYING_ROOT_RISE_M) -> FrameIndex:
    """Only the frames where the robot still lies: root at most ``max_rise_m`` above its start height.

    A human character's root can be guided by virtual forces (paper 000 section 4.3); a robot's
    cannot: a planned path between two lying postures only moves the joints, so a connecting
    frame where the motion has already lifted the body (on all fours, kneeling) is one the robot
    cannot reach from the floor by the plan. Those frames stay out of the selection.
    """
    keep = np.zeros(index.size, dtype=bool)
    for mid, name in enumerate(index.motion_names):
        motion = library.get(name)
        rows = np.flatnonzero(index.motion_id == mid)
        z = motion.trajectory.root[index.frame[rows], 2] if motion.trajectory.root is not None else np.zeros(rows.size)
        keep[rows] = z <= motion.start.root_pos[2] + max_rise_m
    rows = np.flatnonzero(keep)
    fields = {
        f.name: (getattr(index, f.name)[rows] if isinstance(getattr(index, f.name), np.ndarray) and getattr(index, f.name).shape[:1] == (index.size,) else getattr(index, f.name))
        for f in dataclasses.fields(index)
    }
    return FrameIndex(**fields)


def connection_candidates(
    library: MotionLibrary,
    robot: Robot,
    start: Posture,
    k: int,
    *,
    index: FrameIndex | None = None,
    tree: KMeansTree | None = None,
    rank: str = "distance",
) -> list[Connection]:
    """Connecting frames of ``k`` motions, best first.

    ``rank="distance"``: the nearest frame of the ``k`` nearest motions (paper 000 eq. 1); the very
    nearest comes from the K-means tree (paper 000 section 4.1), the runners-up per motion from the
    same frame index. ``rank="duration"``: per motion, its nearest frame among those whose root is
    within ``MAX_ROOT_TURN_RAD`` of the start's (a plan moves the joints, not the body; a prone
    motion's within ``MAX_ROLL_ONTO_FRONT_RAD``: a side rolls onto its front); motions
    ordered by the expected get-up through that frame (:func:`expected_getup_s`: the approach at the
    servos' speed plus the rest of the motion; issue 17: join the library where it pays), the
    two nearest motions kept as the runners-up. When the quickest is a motion with a timing window
    of its own (``Motion.max_stretch``), the quickest motion without one is tried next, before the
    nearest, and up to ``k`` + 1 candidates are returned (the ``k`` - 1 runners-up stay).
    """
    index = index or FrameIndex.build(library, robot)
    joints = start.joint_vector(robot.joint_names)
    q, jw = index.query_features(start.root_quat_wxyz, joints)
    d = index.distances(q, jw)
    if rank not in ("distance", "duration"):
        raise ValueError(f"rank must be 'distance' or 'duration', not {rank!r}")
    tree = tree or KMeansTree(index)
    best = tree.query(start.root_quat_wxyz, joints)
    by_distance = [best]
    for mid, name in enumerate(index.motion_names):
        if name == best.motion:
            continue
        rows = np.flatnonzero(index.motion_id == mid)
        if rows.size:
            i = int(rows[np.argmin(d[rows])])
            by_distance.append(index._connection(i, float(d[i]), int(rows.size)))
    by_distance[1:] = sorted(by_distance[1:], key=lambda c: c.distance)
    if rank == "distance":
        return by_distance[:k]
    expected, turn = expected_getup_s(index, library, robot, start)
    scored = []
    for mid in range(len(index.motion_names)):
        reach = MAX_ROLL_ONTO_FRONT_RAD if library.get(index.motion_names[mid]).lying == "prone" else MAX_ROOT_TURN_RAD
        rows = np.flatnonzero((index.motion_id == mid) & (turn <= reach))
        if rows.size:
            # the motion's nearest frame (a later frame's shorter rest did not pay: its longer
            # approach failed or outlasted the estimate), the motions ordered by expected time
            i = int(rows[np.argmin(d[rows])])
            scored.append((float(expected[i]), index._connection(i, float(d[i]), int(rows.size))))
    quickest = [c for _, c in sorted(scored, key=lambda x: x[0])]
    # the quickest first; a motion with a timing window of its own (``max_stretch``: it stands
    # only near its own timing, from few random starts) does not hold that place alone: the
    # quickest motion without one follows it (OP3, seed 1: supine starts whose sit-up failed went
    # to the nearest, the 6.1 s backroll, not the roll, 4.4 s then)
    lead = next((n + 1 for n, c in enumerate(quickest) if library.get(c.motion).max_stretch is None), 1)
    # then the two nearest are the runners-up (if the quickest fails, the safest next: with a side
    # free to roll onto its front, the next quickest is often another prone motion that fails
    # the same way), then the other quick ones, then the nearest of the rest
    out: list[Connection] = []
    for c in quickest[:lead] + by_distance[:2] + quickest[lead:] + by_distance[2:]:
        if all((c.motion, c.frame) != (o.motion, o.frame) for o in out) and all(c.motion != o.motion for o in out):
            out.append(c)
    return out[:k + min(lead, 2) - 1]  # the one that follows a timing window's motion comes on top


def expected_getup_s(index: FrameIndex, library: MotionLibrary, robot: Robot, start: Posture) -> tuple[np.ndarray, np.ndarray]:
    """Per frame: the expected get-up time from ``start`` through it [s], and the root turn to it [rad].

    The approach takes the slowest joint's trapezoid at the planner's timing limits (speed
    JOINT_SPEED_FRACTION_OF_NO_LOAD x no-load, acceleration ``Robot.joint_accel_limits_rad_s2``),
    or the root's turn at its angular speed limit if longer; then the motion plays from that frame
    to its end.
    """
    v = np.array([s.no_load_speed_at(robot.supply_voltage_v) for s in robot.servo_datasheets()]) * JOINT_SPEED_FRACTION_OF_NO_LOAD
    a = robot.joint_accel_limits_rad_s2(JOINT_SPEED_FRACTION_OF_NO_LOAD)
    frame_joints = index.joints_w / index.sqrt_w
    dist = np.abs(frame_joints - start.joint_vector(robot.joint_names))
    ramp = v * v / a  # distance covered accelerating to full speed and back
    t_joint = np.where(dist > ramp, dist / v + v / a, 2.0 * np.sqrt(dist / a)).max(axis=1)
    q = np.asarray(start.root_quat_wxyz, dtype=float)
    q = q / np.linalg.norm(q)
    c1, c2 = index.quat @ q, index.quat_z @ q
    turn = 2.0 * np.arccos(np.minimum(np.sqrt(c1 * c1 + c2 * c2), 1.0))
    t_root = turn / ROOT_ANGULAR_SPEED_LIMIT_RAD_S
    remaining = np.array([library.get(index.motion_names[m]).trajectory.duration_s for m in index.motion_id]) - index.time_s
    return APPROACH_TIME_FACTOR * np.maximum(t_joint, t_root) + remaining, turn


def connecting_posture(library: MotionLibrary, robot: Robot, connection: Connection, start: Posture, checker: ValidityChecker) -> Posture:
    """The connecting posture of a connection, placed where the robot lies (placement.place_near).

    The planner then plans the root there (paper 000 section 4.2.1 plans the root position when
    the postures differ in it); the dynamics filter decides whether the robot can get there.
    """
    motion = library.get(connection.motion)
    tr = motion.trajectory
    cols = [tr.joint_names.index(j) for j in robot.joint_names]
    root = tr.root[connection.frame] if tr.root is not None else np.concatenate([motion.start.root_pos, motion.start.root_quat_wxyz])
    # Library targets may graze a limit by rounding; the planner needs a goal inside the limits.
    joints = np.clip(tr.q[connection.frame, cols], robot.joint_lower, robot.joint_upper)
    goal = Posture(robot.name, root[:3], root[3:], dict(zip(robot.joint_names, joints)))
    return place_near(goal, start, checker)


@lru_cache(maxsize=4)
def _cached_selection(directory: str, robot_dir: str, scene: str) -> tuple[MotionLibrary, FrameIndex, KMeansTree, ValidityChecker]:
    from robot_rise.model import load_robot

    robot = load_robot(robot_dir)
    lib = load_library(directory if directory is not None else robot_library_dir(robot))
    index = lying_frames(FrameIndex.build(lib, robot), lib)
    return lib, index, KMeansTree(index), ValidityChecker(robot, scene)


def select_connecting_posture(
    start: Posture, robot: Robot, *, directory: str | os.PathLike[str] | None = None, scene: str = "flat"
) -> Posture:
    """The connecting posture for a lying posture: the nearest lying frame of the library
    (:func:`connection_candidates`, first) placed where the robot lies (:func:`connecting_posture`),
    as ``rise`` selects its first candidate. The library, its frame index and tree are built once
    per (library, robot, scene).
    """
    lib_dir = str(Path(directory) if directory is not None else robot_library_dir(robot))
    lib, index, tree, checker = _cached_selection(lib_dir, str(robot.directory), scene)
    conn = connection_candidates(lib, robot, start, 1, index=index, tree=tree)[0]
    log.info("connecting posture: %s frame %d (t = %.2f s), distance %.3f", conn.motion, conn.frame, conn.time_s, conn.distance)
    return connecting_posture(lib, robot, conn, start, checker)
