"""Connecting-posture selection: the nearest library frame, turned and placed where the robot lies (paper 000 section 4.1)."""

from __future__ import annotations

import logging
import os
from functools import lru_cache
from pathlib import Path

import numpy as np

from robot_rise.errors import FormatError
from robot_rise.library.frames import Connection, FrameIndex
from robot_rise.library.motions import MotionLibrary, default_library_dir, load_library
from robot_rise.library.tree import KMeansTree
from robot_rise.model import Robot
from robot_rise.posture import Posture, quat_multiply

__all__ = ["connection_posture", "select_connecting_posture"]

log = logging.getLogger(__name__)

_QUAT_Z = np.array([0.0, 0.0, 0.0, 1.0])


@lru_cache(maxsize=4)
def _cached_tree(directory: str, robot_dir: str) -> tuple[MotionLibrary, KMeansTree, object]:
    from robot_rise.model import load_robot
    from robot_rise.validity import ValidityChecker

    robot = load_robot(robot_dir)
    lib = load_library(directory, robot_name=robot.name)
    return lib, KMeansTree(FrameIndex.build(lib, robot)), ValidityChecker(robot, None)


def connection_posture(library: MotionLibrary, robot: Robot, connection: Connection, start: Posture) -> Posture:
    """The frame of ``connection`` as a posture, turned about world z to face like ``start`` and
    moved over it (x, y of ``start``, height of the frame)."""
    motion = library.get(connection.motion)
    tr = motion.trajectory
    if tr.root is None:
        raise FormatError(f"motion {motion.name}: no 'root' pose per row")
    root = np.asarray(tr.root[connection.frame], dtype=float)
    q2 = root[3:] / np.linalg.norm(root[3:])
    q1 = np.asarray(start.root_quat_wxyz, dtype=float)
    a, b = float(q1 @ q2), float(q1 @ quat_multiply(_QUAT_Z, q2))
    n = float(np.hypot(a, b))
    turn = np.array([a / n, 0.0, 0.0, b / n]) if n > 1e-12 else np.array([1.0, 0.0, 0.0, 0.0])
    quat = quat_multiply(turn, q2)
    cols = [tr.joint_names.index(j) for j in robot.joint_names]
    joints = dict(zip(robot.joint_names, (float(x) for x in tr.q[connection.frame, cols])))
    return Posture(robot.name, np.array([start.root_pos[0], start.root_pos[1], root[2]]), quat, joints)


def select_connecting_posture(start: Posture, robot: Robot, *, directory: str | os.PathLike[str] | None = None) -> Posture:
    """Connecting posture for a lying posture (paper 000 section 4.1): the nearest library frame
    of a lying-to-squatting phase, turned and placed where the robot lies.

    The library and its K-means tree are built once per (library, robot) directory pair. The
    simulated frame sinks a few millimetres into the soft contact; the returned posture is lifted
    so that its lowest point rests exactly on z = 0 (flat ground).
    """
    lib_dir = str(Path(directory) if directory is not None else default_library_dir(robot.name))
    lib, tree, checker = _cached_tree(lib_dir, str(robot.directory))
    conn = tree.query(start.root_quat_wxyz, start.joint_vector(robot.joint_names))
    log.info("connecting posture: %s frame %d (t = %.2f s), distance %.3f", conn.motion, conn.frame, conn.time_s, conn.distance)
    goal = connection_posture(lib, robot, conn, start)
    low = checker.lowest_point_z(checker.qpos_of(goal))  # type: ignore[attr-defined]
    return goal.with_root(root_pos=goal.root_pos - np.array([0.0, 0.0, low]))
