"""The motion library and connecting-posture selection (paper 000 section 4.1, section 4.3).

A library directory holds ``index.json`` (format ``robot-rise/motion-library@1``) naming, per
motion, a trajectory file (``robot-rise/trajectory@1`` with the simulated ``root`` pose per row), its
start posture file and ``connect_until_s``, the end of the lying-to-sitting/squatting phase.

Connecting-posture selection: every row of every motion's lying-to-sitting phase is a candidate
frame. For an arbitrary lying posture we want the frame nearest by the posture metric of paper 000
eq. (1)-(3) (root orientation after yaw alignment, weighted joint angles). The paper clusters the
frames with K-means into an N-ary tree (N = 50 for its motion-capture database) and descends it.
Our tree is exact: the metric is a true metric (a sum of the bi-invariant, yaw-quotiented SO(3)
distance and a weighted Euclidean one), so each node keeps a centre frame and a covering radius
and a best-first search prunes a node when d(query, centre) - radius cannot beat the best frame
found so far (triangle inequality). The answer is therefore always the brute-force answer; the
tree only saves distance evaluations.

Branching factor: N = 50 as in the paper, leaves of at most 40 frames. Measured over N in
{8, 12, 20, 30, 40, 50} (BENCHMARKS.md, motion library section): with under two thousand frames a wide,
shallow tree (depth 3) is fastest, because each level is searched with one vectorised call and the
per-call overhead, not the number of distances, dominates in Python.
"""

from __future__ import annotations

import json
import logging
import os
import time
import warnings
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from robot_rise.errors import FormatError
from robot_rise.model import Robot
from robot_rise.paths import configs_dir
from robot_rise.posture import Posture, quat_multiply, read_posture
from robot_rise.trajectory import Trajectory, read_trajectory

__all__ = [
    "LIBRARY_FORMAT",
    "LYING_KINDS",
    "Motion",
    "MotionLibrary",
    "load_library",
    "default_library_dir",
    "FrameIndex",
    "Connection",
    "KMeansTree",
    "TREE_BRANCHING",
    "TREE_LEAF_SIZE",
    "select_connecting_posture",
    "connection_posture",
]

log = logging.getLogger(__name__)

LIBRARY_FORMAT = "robot-rise/motion-library@1"
LYING_KINDS = ("supine", "prone", "left", "right")
TREE_BRANCHING = 50  # N of the N-ary K-means tree: paper 000 section 4.1 uses 50 (see module docstring)
TREE_LEAF_SIZE = 40  # a node with at most this many frames is a leaf (ours, measured)
# Groups searched by KMeansTree.query (ours, measured on 1,000 random lying postures against brute
# force: 2 groups 99.7 %, 4 groups 99.8 %, 6 groups 100 % agreement; see BENCHMARKS.md).
TREE_PROBE_GROUPS = 4
_QUAT_Z = np.array([0.0, 0.0, 0.0, 1.0])


def default_library_dir(robot_name: str = "op3") -> Path:
    """The shipped library of a robot: ``configs/motions/<robot>``."""
    return configs_dir() / "motions" / robot_name


@dataclass(frozen=True)
class Motion:
    """One library motion.

    Attributes:
        name: motion name (file stem).
        lying: ``supine``, ``prone``, ``left`` or ``right``.
        strategy: one line for people.
        trajectory: the joint-target trajectory (with the simulated root pose per row).
        start: the settled lying posture it starts from.
        connect_until_s: end of the lying-to-sitting/squatting phase [s].
    """

    name: str
    lying: str
    strategy: str
    trajectory: Trajectory
    start: Posture
    connect_until_s: float

    @property
    def duration_s(self) -> float:
        return self.trajectory.duration_s


@dataclass(frozen=True)
class MotionLibrary:
    """The motions of one robot, in index order."""

    robot: str
    directory: Path
    motions: tuple[Motion, ...]

    def names(self) -> list[str]:
        return [m.name for m in self.motions]

    def get(self, name: str) -> Motion:
        """The motion called ``name``; FormatError listing the names otherwise."""
        for m in self.motions:
            if m.name == name:
                return m
        raise FormatError(f"no motion {name!r} in {self.directory}; motions: {', '.join(self.names())}")

    def frame_index(self, robot: Robot) -> FrameIndex:
        """Index the lying-to-sitting phase of every motion (see :class:`FrameIndex`)."""
        return FrameIndex.build(self, robot)


def load_library(directory: str | os.PathLike[str] | None = None, *, robot_name: str = "op3") -> MotionLibrary:
    """Read a library directory (default: the shipped one) and validate every file it names.

    Raises:
        FormatError: the index or a motion file is missing or malformed (the message names it).
    """
    root = Path(directory) if directory is not None else default_library_dir(robot_name)
    path = root / "index.json"
    try:
        obj = json.loads(path.read_text())
    except FileNotFoundError:
        raise FormatError(f"{path}: no motion library index", hint="regenerate with: python -m robot_rise.library_authoring") from None
    except json.JSONDecodeError as e:
        raise FormatError(f"{path}: not valid JSON ({e})") from None
    if not isinstance(obj, dict) or obj.get("format") != LIBRARY_FORMAT:
        got = obj.get("format") if isinstance(obj, dict) else None
        raise FormatError(f"{path}: format is {got!r}, expected {LIBRARY_FORMAT!r}")
    rows = obj.get("motions")
    if not isinstance(rows, list) or not rows:
        raise FormatError(f"{path}: 'motions' must be a non-empty list")
    motions = []
    seen: set[str] = set()
    for i, row in enumerate(rows):
        where = f"{path}: motions[{i}]"
        if not isinstance(row, dict):
            raise FormatError(f"{where}: expected an object")
        for key in ("name", "lying", "trajectory", "start", "connect_until_s"):
            if key not in row:
                raise FormatError(f"{where}: missing field {key!r}")
        name = str(row["name"])
        if name in seen:
            raise FormatError(f"{where}: motion name {name!r} appears twice")
        seen.add(name)
        if row["lying"] not in LYING_KINDS:
            raise FormatError(f"{where}: lying is {row['lying']!r}; expected one of {', '.join(LYING_KINDS)}")
        tr = read_trajectory(root / str(row["trajectory"]))
        start = read_posture(root / str(row["start"]))
        if tr.root is None:
            raise FormatError(f"{root / str(row['trajectory'])}: library motions need the simulated 'root' pose per row")
        cut = float(row["connect_until_s"])
        if not 0.0 < cut <= tr.duration_s:
            raise FormatError(f"{where}: connect_until_s {cut} must lie in (0, {tr.duration_s}]")
        motions.append(Motion(name, str(row["lying"]), str(row.get("strategy", "")), tr, start, cut))
    return MotionLibrary(str(obj.get("robot", robot_name)), root, tuple(motions))


@dataclass(frozen=True)
class Connection:
    """The connecting posture chosen for a query.

    Attributes:
        motion: motion name.
        frame: row index in the motion's trajectory.
        time_s: time of that row [s].
        distance: posture distance of paper 000 eq. (1) to the query.
        evaluations: number of frame distances evaluated to find it.
    """

    motion: str
    frame: int
    time_s: float
    distance: float
    evaluations: int


@dataclass(frozen=True)
class FrameIndex:
    """Candidate frames in the metric's own coordinates (read-only arrays).

    Attributes:
        motion_names: motion per motion id.
        motion_id, frame, time_s: per frame, shape (M,).
        quat: root quaternions (w, x, y, z), shape (M, 4).
        quat_z: the same turned by pi about world z (k * q), shape (M, 4) (yaw alignment).
        joints_w: joint angles times sqrt(w^i) of eq. (3), shape (M, n).
        root_weight: w_q of eq. (1).
        sqrt_w: sqrt of the joint weights, shape (n,).
    """

    motion_names: tuple[str, ...]
    motion_id: np.ndarray
    frame: np.ndarray
    time_s: np.ndarray
    quat: np.ndarray
    quat_z: np.ndarray
    joints_w: np.ndarray
    root_weight: float
    sqrt_w: np.ndarray

    @classmethod
    def build(cls, library: MotionLibrary, robot: Robot) -> FrameIndex:
        mids, frames, times, quats, joints = [], [], [], [], []
        for k, m in enumerate(library.motions):
            tr = m.trajectory
            cols = [tr.joint_names.index(j) for j in robot.joint_names]
            rows = np.flatnonzero(tr.t <= m.connect_until_s + 1e-9)
            if tr.root is None:
                raise FormatError(f"motion {m.name}: no 'root' pose per row to index")
            mids.append(np.full(rows.size, k))
            frames.append(rows)
            times.append(tr.t[rows])
            quats.append(tr.root[rows, 3:])
            joints.append(tr.q[rows][:, cols])
        q = np.concatenate(quats)
        q = q / np.linalg.norm(q, axis=1, keepdims=True)
        sqrt_w = np.sqrt(np.asarray(robot.metric_weights, dtype=float))
        arrays = dict(
            motion_id=np.concatenate(mids),
            frame=np.concatenate(frames),
            time_s=np.concatenate(times),
            quat=q,
            quat_z=quat_multiply(_QUAT_Z, q),
            joints_w=np.concatenate(joints) * sqrt_w,
        )
        for a in arrays.values():
            a.setflags(write=False)
        return cls(tuple(library.names()), root_weight=robot.root_orientation_weight, sqrt_w=sqrt_w, **arrays)

    @property
    def size(self) -> int:
        return int(self.frame.size)

    def query_features(self, quat_wxyz: np.ndarray, joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(unit quaternion shape (4,), weighted joints shape (n,)) of a query posture."""
        q = np.asarray(quat_wxyz, dtype=float)
        return q / np.linalg.norm(q), np.asarray(joints, dtype=float) * self.sqrt_w

    def distances(self, q: np.ndarray, jw: np.ndarray, rows: np.ndarray | slice = slice(None)) -> np.ndarray:
        """Paper 000 eq. (1) from a query (features) to frames ``rows``, shape (len(rows),).

        Same value as :class:`robot_rise.posture.PostureDistance`, with the yaw alignment and the
        weights precomputed per frame.
        """
        a = self.quat[rows] @ q
        b = self.quat_z[rows] @ q
        dq = np.arccos(np.minimum(np.sqrt(a * a + b * b), 1.0))
        dv = np.sqrt(np.sum((self.joints_w[rows] - jw) ** 2, axis=1))
        return self.root_weight * dq + dv

    def pairwise(self, i: int, rows: np.ndarray) -> np.ndarray:
        """Distances from frame ``i`` to frames ``rows``."""
        return self.distances(self.quat[i], self.joints_w[i], rows)

    def _connection(self, i: int, d: float, evaluations: int) -> Connection:
        return Connection(self.motion_names[self.motion_id[i]], int(self.frame[i]), float(self.time_s[i]), float(d), evaluations)

    def brute_force(self, quat_wxyz: np.ndarray, joints: np.ndarray) -> Connection:
        """Nearest frame by evaluating every frame."""
        q, jw = self.query_features(quat_wxyz, joints)
        d = self.distances(q, jw)
        i = int(np.argmin(d))
        return self._connection(i, float(d[i]), self.size)

    def features(self) -> np.ndarray:
        """Euclidean features for K-means: weighted joints and w_q times the body-frame up vector, shape (M, n + 3).

        The up vector seen from the body (third row of R) ignores yaw, like the metric does.
        """
        w, x, y, z = self.quat.T
        up = np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=1)
        return np.concatenate([self.joints_w, self.root_weight * 0.5 * up], axis=1)


@dataclass(frozen=True)
class _Node:
    centre: int  # frame index of the node's centre (a member frame)
    radius: float  # max metric distance from the centre to any member
    members: np.ndarray  # frame indices (leaves only; empty for inner nodes)
    children: tuple[_Node, ...]
    child_centres: np.ndarray  # centre frame of each child, shape (len(children),)
    child_radii: np.ndarray  # covering radius of each child, shape (len(children),)


class KMeansTree:
    """N-ary K-means tree over a :class:`FrameIndex` with exact best-first search."""

    def __init__(self, index: FrameIndex, *, branching: int = TREE_BRANCHING, leaf_size: int = TREE_LEAF_SIZE, seed: int = 0) -> None:
        if branching < 2:
            raise ValueError("branching must be >= 2")
        self.index = index
        self.branching = branching
        self.leaf_size = leaf_size
        self._rng = np.random.default_rng(seed)
        self._features = index.features()
        t0 = time.perf_counter()
        self.root = self._build(np.arange(index.size))
        self._index_groups()
        self.build_time_s = time.perf_counter() - t0
        log.debug("K-means tree over %d frames built in %.3f s", index.size, self.build_time_s)

    def _make_node(self, rows: np.ndarray, children: tuple[_Node, ...], members: np.ndarray) -> _Node:
        f = self._features[rows]
        centre = int(rows[int(np.argmin(np.sum((f - f.mean(axis=0)) ** 2, axis=1)))])
        radius = float(self.index.pairwise(centre, rows).max())
        cc = np.array([c.centre for c in children], dtype=int)
        cr = np.array([c.radius for c in children], dtype=float)
        return _Node(centre, radius, members, children, cc, cr)

    def _build(self, rows: np.ndarray) -> _Node:
        if rows.size <= self.leaf_size:
            return self._make_node(rows, (), rows)
        k = min(self.branching, rows.size)
        seed = int(self._rng.integers(2**31 - 1))
        with warnings.catch_warnings():  # empty clusters are dropped below
            warnings.simplefilter("ignore")
            from scipy.cluster.vq import kmeans2  # imported here: scipy.cluster costs ~0.5 s at CLI start-up

            _, labels = kmeans2(self._features[rows], k, minit="++", seed=seed)
        groups = [rows[labels == g] for g in range(k) if np.any(labels == g)]
        if len(groups) < 2:  # identical frames: split arbitrarily
            groups = list(np.array_split(rows, 2))
        return self._make_node(rows, tuple(self._build(g) for g in groups), np.empty(0, dtype=int))

    def _index_groups(self) -> None:
        """The root's groups (paper 000 section 4.1: "the root node contains the representative
        posture of each group"), each laid out as one contiguous slice of frames for the search."""
        groups = self.root.children or (self.root,)

        def members(node: _Node) -> np.ndarray:
            return node.members if node.members.size else np.concatenate([members(c) for c in node.children])

        rows = [members(g) for g in groups]
        order = np.concatenate(rows)
        idx = self.index
        self._g_bounds = np.cumsum([0] + [r.size for r in rows])
        self._g_rows = [np.arange(self._g_bounds[g], self._g_bounds[g + 1]) for g in range(len(rows))]
        self._g_order = order
        self._g_quat, self._g_quat_z, self._g_joints_w = (np.ascontiguousarray(a[order]) for a in (idx.quat, idx.quat_z, idx.joints_w))
        centres = np.array([g.centre for g in groups], dtype=int)
        self._c_quat, self._c_quat_z, self._c_joints_w = (np.ascontiguousarray(a[centres]) for a in (idx.quat, idx.quat_z, idx.joints_w))

    def _distances(self, quat: np.ndarray, quat_z: np.ndarray, joints_w: np.ndarray, q: np.ndarray, jw: np.ndarray) -> np.ndarray:
        a = quat @ q
        b = quat_z @ q
        diff = joints_w - jw
        return self.index.root_weight * np.arccos(np.minimum(np.sqrt(a * a + b * b), 1.0)) + np.sqrt(np.einsum("ij,ij->i", diff, diff))

    def query(self, quat_wxyz: np.ndarray, joints: np.ndarray, *, probe: int = TREE_PROBE_GROUPS) -> Connection:
        """Nearest frame by the paper's tree search: the ``probe`` groups whose representative is
        nearest, then the nearest frame within them (paper 000 section 4.1).

        Not exact by construction; measured against brute force in BENCHMARKS.md (issue 4 asks
        for >= 99 % agreement). :meth:`query_exact` is the exact branch-and-bound search.
        """
        q, jw = self.index.query_features(quat_wxyz, joints)
        dc = self._distances(self._c_quat, self._c_quat_z, self._c_joints_w, q, jw)
        groups = np.argpartition(dc, probe - 1)[:probe] if probe < dc.size else np.arange(dc.size)
        rows = np.concatenate([self._g_rows[g] for g in groups])  # one gather: per-call overhead dominates
        d = self._distances(self._g_quat[rows], self._g_quat_z[rows], self._g_joints_w[rows], q, jw)
        j = int(np.argmin(d))
        return self.index._connection(int(self._g_order[rows[j]]), float(d[j]), int(dc.size + rows.size))

    def query_exact(self, quat_wxyz: np.ndarray, joints: np.ndarray) -> Connection:
        """Nearest frame (exact: equal to :meth:`FrameIndex.brute_force` up to ties).

        Level-synchronous branch and bound: per level, the centres of all live nodes' children are
        evaluated in one vectorised call (each centre is a frame, so it also improves the best
        answer), children whose bound d(query, centre) - radius cannot beat the best are dropped,
        the surviving leaves are evaluated in one call, and the surviving inner nodes form the next
        level. Few numpy calls per query, whatever the number of nodes visited.
        """
        idx = self.index
        q, jw = idx.query_features(quat_wxyz, joints)
        best_d, best_i, evals = np.inf, -1, 0
        frontier = [self.root]
        while frontier:
            kids = [c for n in frontier for c in n.children]
            if not kids:
                break
            centres = np.concatenate([n.child_centres for n in frontier])
            radii = np.concatenate([n.child_radii for n in frontier])
            dc = idx.distances(q, jw, centres)
            evals += centres.size
            j = int(np.argmin(dc))
            if dc[j] < best_d:
                best_d, best_i = float(dc[j]), int(centres[j])
            live = np.flatnonzero(dc - radii < best_d)
            leaves = [kids[k] for k in live if kids[k].members.size]
            if leaves:
                rows = np.concatenate([n.members for n in leaves])
                d = idx.distances(q, jw, rows)
                evals += rows.size
                j = int(np.argmin(d))
                if d[j] < best_d:
                    best_d, best_i = float(d[j]), int(rows[j])
            frontier = [kids[k] for k in live if not kids[k].members.size and dc[k] - radii[k] < best_d]
        if self.root.members.size:  # the whole index is one leaf
            d = idx.distances(q, jw, self.root.members)
            evals += d.size
            j = int(np.argmin(d))
            best_d, best_i = float(d[j]), int(self.root.members[j])
        return idx._connection(best_i, best_d, evals)

    def depth(self) -> int:
        def _d(n: _Node) -> int:
            return 1 + max((_d(c) for c in n.children), default=0)

        return _d(self.root)


@lru_cache(maxsize=4)
def _cached_tree(directory: str, robot_dir: str) -> tuple[MotionLibrary, KMeansTree, object]:
    from robot_rise.model import load_robot
    from robot_rise.validity import ValidityChecker

    robot = load_robot(robot_dir)
    lib = load_library(directory, robot_name=robot.name)
    return lib, KMeansTree(lib.frame_index(robot)), ValidityChecker(robot, None)


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
