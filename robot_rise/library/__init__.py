"""The motion library: motions as data (loading), the frames to join them at, and connecting-posture selection.

- :mod:`~robot_rise.library.motions`: ``index.json`` and its motions, read and validated; the library's digest.
- :mod:`~robot_rise.library.frames`: candidate frames and the posture metric over them.
- :mod:`~robot_rise.library.tree`: the K-means tree that finds the nearest frame.
- :mod:`~robot_rise.library.selection`: the connecting posture for a lying robot.
"""

from robot_rise.library.frames import Connection, FrameIndex
from robot_rise.library.motions import LIBRARY_FORMAT, LYING_KINDS, Motion, MotionLibrary, default_library_dir, library_digest, load_library, robot_library_dir
from robot_rise.library.strategies import STRATEGY_FORMAT, RoleKeyframe, Strategy, joint_keyframes, load_strategies, read_strategy
from robot_rise.library.selection import LYING_ROOT_RISE_M, connecting_posture, connection_candidates, lying_frames, select_connecting_posture
from robot_rise.library.tree import TREE_BRANCHING, TREE_LEAF_SIZE, KMeansTree

__all__ = [
    "LIBRARY_FORMAT",
    "LYING_KINDS",
    "Motion",
    "MotionLibrary",
    "load_library",
    "default_library_dir",
    "robot_library_dir",
    "library_digest",
    "STRATEGY_FORMAT",
    "RoleKeyframe",
    "Strategy",
    "joint_keyframes",
    "load_strategies",
    "read_strategy",
    "FrameIndex",
    "Connection",
    "KMeansTree",
    "TREE_BRANCHING",
    "TREE_LEAF_SIZE",
    "select_connecting_posture",
    "connection_candidates",
    "connecting_posture",
    "lying_frames",
    "LYING_ROOT_RISE_M",
]
