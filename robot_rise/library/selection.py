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

from robot_rise.library.frames import Connection, FrameIndex
from robot_rise.library.motions import MotionLibrary, load_library, robot_library_dir
from robot_rise.library.tree import KMeansTree
from robot_rise.model import Robot
from robot_rise.placement import place_near
from robot_rise.posture import Posture
from robot_rise.validity import ValidityChecker

__all__ = ["LYING_ROOT_RISE_M", "lying_frames", "connection_candidates", "connecting_posture", "select_connecting_posture"]

log = logging.getLogger(__name__)

LYING_ROOT_RISE_M = 0.02  # a library frame counts as lying while its root is this close to the start's height


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
    library: MotionLibrary, robot: Robot, start: Posture, k: int, *, index: FrameIndex | None = None, tree: KMeansTree | None = None
) -> list[Connection]:
    """The nearest frame of the ``k`` nearest motions (paper 000 eq. 1), nearest first.

    The very nearest comes from the K-means tree (paper 000 section 4.1); the runners-up per
    motion from the same frame index.
    """
    index = index or FrameIndex.build(library, robot)
    tree = tree or KMeansTree(index)
    joints = start.joint_vector(robot.joint_names)
    best = tree.query(start.root_quat_wxyz, joints)
    q, jw = index.query_features(start.root_quat_wxyz, joints)
    d = index.distances(q, jw)
    out = [best]
    for mid, name in enumerate(index.motion_names):
        if name == best.motion:
            continue
        rows = np.flatnonzero(index.motion_id == mid)
        if rows.size:
            i = int(rows[np.argmin(d[rows])])
            out.append(index._connection(i, float(d[i]), int(rows.size)))
    out[1:] = sorted(out[1:], key=lambda c: c.distance)
    return out[:k]


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
