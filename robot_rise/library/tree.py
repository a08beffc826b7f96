"""The N-ary K-means tree over library frames, with exact best-first search (paper 000 section 4.1).

The paper clusters the
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

import logging
import time
import warnings
from dataclasses import dataclass

import numpy as np

from robot_rise.library.frames import Connection, FrameIndex

__all__ = ["KMeansTree", "TREE_BRANCHING", "TREE_LEAF_SIZE", "TREE_PROBE_GROUPS"]

log = logging.getLogger(__name__)

TREE_BRANCHING = 50  # N of the N-ary K-means tree: paper 000 section 4.1 uses 50 (see module docstring)
TREE_LEAF_SIZE = 40  # a node with at most this many frames is a leaf (ours, measured)
# Groups searched by KMeansTree.query (ours, measured on 1,000 random lying postures against brute
# force: 2 groups 99.7 %, 4 groups 99.8 %, 6 groups 100 % agreement; see BENCHMARKS.md).
TREE_PROBE_GROUPS = 4


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
