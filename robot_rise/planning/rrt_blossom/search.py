"""RRT-blossom in posture space (paper 000 section 3.2, Fig. 2; section 4.2.1).

Two trees grow from the two ends. EXTEND_BLOSSOM picks the nearest live node of a tree, steps
toward the sample with eq. (4)-(5) (the main child) and blossoms further children within the
+-15 degree span per joint DOF around it; each child is kept unless its edge fails
(FAILURE: limits, ground, self and obstacle collision of the motion, checked by the
MotionValidator) or it regresses (a node of the tree is nearer to it than its parent).

Edge viability (Kalisiak & van de Panne 2006, paper 000 Fig. 4): each node carries the state of
the edge into it: untried (added, never expanded), live (expanded, and it or a child may still
grow), dormant (everything tried from it regressed, or led only to dormant nodes) or dead
(everything collided, or led only to dead nodes). Only untried and live nodes that have
expansions left are nearest-neighbour candidates. A node that has used its expansions and has
no untried or live child becomes dormant or dead, and its parent is asked the same question:
blocked regions recede instead of trapping the search.

Choices of ours, each a knob of :class:`BlossomConfig`:
- root position is a third part of the state stepped by its own eps_p, with the same
  unsynchronised-termination rule as orientation and joints (a part that has reached the
  sample's value stays fixed while the others are planned), instead of a separate
  root-position pre-pass (the paper does not say what that pass is checked against);
- a node may be expanded ``max_expansions`` times (toward different samples) before it is
  closed; the paper's 2-D version has a fixed control set U per node, ours depends on the sample;
- the tree answering an extension greedily extends again toward the new node while that
  brings it nearer (RRT-Connect's CONNECT, of which RRT-blossom is a variant), and two nodes
  closer than ``connect_distance`` join if the straight motion between them is legal;
- samples (the paper does not say how it draws them): a goal bias, then half from the whole
  space (uniform SO(3) root orientation, root in a box around the ends, joints within limits)
  and half near the straight start-goal motion; without the uniform half the search could not
  leave the neighbourhood of the slerp (see ``BlossomConfig.uniform_share``);
- ``free_joints`` restricts exploration to some joints (partial-body planning, section 4.2.3):
  the other DOFs, root included, stay on the straight motion between the two ends.

Deterministic for a seed: all randomness comes from one numpy Generator; the clock only decides
when to stop.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np

from robot_rise.constants import (
    BLOSSOM_SPAN_RAD,
    BLOSSOM_STEP_JOINT_RAD,
    BLOSSOM_STEP_ORIENTATION_RAD,
    BLOSSOM_STEP_POSITION_M,
)
from robot_rise.planning.motion_validator import MotionValidator

__all__ = ["BlossomConfig", "BlossomOutcome", "EdgeState", "rrt_blossom", "uniform_quaternion"]

log = logging.getLogger(__name__)

# Ours (not in paper 000, whose samples are not specified): a share of samples from the whole
# space keeps the search probabilistically complete in root orientation (see BlossomConfig).
UNIFORM_SAMPLE_SHARE = 0.5  # measured: 0 / 0.2 / 0.5 / 0.6 on hard supine-to-prone problems, see BENCHMARKS.md
UNIFORM_BOX_XY_M = 0.3  # root box beyond the two ends in x, y [m] (the OMPL adapter's bounds)
UNIFORM_BOX_UP_M = 0.3  # and above them [m]: room for the root of a 0.51 m robot turning over


def uniform_quaternion(rng: np.random.Generator) -> np.ndarray:
    """A uniformly distributed unit quaternion (w, x, y, z) (Shoemake 1992), shape (4,)."""
    u1, u2, u3 = rng.random(3)
    a, b = np.sqrt(1.0 - u1), np.sqrt(u1)
    return np.array([a * np.sin(2 * np.pi * u2), a * np.cos(2 * np.pi * u2), b * np.sin(2 * np.pi * u3), b * np.cos(2 * np.pi * u3)])


class EdgeState:
    """Viability of the edge into a node (paper 000 Fig. 4)."""

    UNTRIED = 0
    LIVE = 1
    DORMANT = 2
    DEAD = 3


@dataclass(frozen=True)
class BlossomConfig:
    """Knobs of RRT-blossom (see the module docstring for which are the paper's).

    Attributes:
        step_joint_rad: eps_e of eq. (5), weighted joint norm [rad].
        step_orientation_rad: eps_q of eq. (4), eq. (2) half-angle [rad].
        step_position_m: eps_p, root travel per step [m].
        span_rad: blossom span per joint DOF around the main child [rad] (000 section 4.2.1).
        n_children: children blossomed besides the main one.
        max_expansions: expansions of one node before it is closed.
        root_expansions: the same for the two roots (a lying start touches the ground, so most
            directions from it collide; closing it early would end the search).
        goal_bias: probability of sampling the other tree's root.
        connect_distance: planner distance under which two nodes of the two trees may join.
        connect_steps: greedy extensions of the answering tree per iteration.
        max_nodes: per tree; reaching it ends the search with a failure.
        sample_orientation_rad: random root rotation around the start-goal slerp in samples [rad].
        sample_position_m: random root offset around the start-goal line in samples [m].
        uniform_share: probability that a (non-goal) sample is drawn from the whole space:
            uniform root orientation on SO(3), root position uniform in the box around the two
            ends (``uniform_box_m``), joints uniform within their limits. Without it the
            samples stay near the start-goal slerp; when that slerp is a somersault (supine to
            prone with the head turned round) the legal way, a roll about the body's long
            axis, lies ~90 degrees off it and is never sampled: the search ran out of time.
        uniform_box_m: half-extent of that box beyond the two ends' root positions in x and y,
            and up (z) [m]; downward it extends by ``sample_position_m / 4``.
    """

    step_joint_rad: float = BLOSSOM_STEP_JOINT_RAD
    step_orientation_rad: float = BLOSSOM_STEP_ORIENTATION_RAD
    step_position_m: float = BLOSSOM_STEP_POSITION_M
    span_rad: float = BLOSSOM_SPAN_RAD
    n_children: int = 3
    max_expansions: int = 4
    root_expansions: int = 2000
    goal_bias: float = 0.1
    connect_distance: float = 1.0
    connect_steps: int = 20
    max_nodes: int = 20000
    sample_orientation_rad: float = 0.8
    sample_position_m: float = 0.1
    uniform_share: float = UNIFORM_SAMPLE_SHARE
    uniform_box_m: tuple[float, float] = (UNIFORM_BOX_XY_M, UNIFORM_BOX_UP_M)


@dataclass(frozen=True)
class BlossomOutcome:
    """Result of one RRT-blossom search.

    Attributes:
        path: states from ``a`` to ``b``, shape (K, 7 + n), or None.
        reason: why there is no path (empty on success).
        timed_out: the deadline ended the search.
        stats: iterations, nodes per tree, edge states, checks, seconds.
    """

    path: np.ndarray | None
    reason: str = ""
    timed_out: bool = False
    stats: dict[str, float] = field(default_factory=dict)


class Tree:
    """Nodes in preallocated arrays; the edge state of node i is that of the edge parent -> i."""

    def __init__(self, root: np.ndarray, cap: int) -> None:
        self.x = np.empty((cap, root.size))
        self.x[0] = root
        self.parent = np.full(cap, -1, dtype=np.int64)
        self.state = np.full(cap, EdgeState.UNTRIED, dtype=np.int8)
        self.state[0] = EdgeState.LIVE
        self.expansions = np.zeros(cap, dtype=np.int32)
        self.candidate = np.zeros(cap, dtype=bool)  # live and not closed: nearest-neighbour set
        self.candidate[0] = True
        self.dormant_hits = np.zeros(cap, dtype=np.int32)
        self.dead_hits = np.zeros(cap, dtype=np.int32)
        self.children: list[list[int]] = [[]]
        self.n = 1
        self.cap = cap

    def add(self, x: np.ndarray, parent: int) -> int:
        i = self.n
        self.x[i] = x
        self.parent[i] = parent
        self.state[i] = EdgeState.UNTRIED
        self.candidate[i] = True
        self.children.append([])
        self.children[parent].append(i)
        self.n += 1
        return i

    def branch(self, i: int) -> list[int]:
        """Indices from the root to node i."""
        out = [i]
        while self.parent[out[-1]] >= 0:
            out.append(int(self.parent[out[-1]]))
        return out[::-1]

    def close(self, i: int, max_expansions: int) -> None:
        """Node i has used its expansions: it leaves the nearest-neighbour set; if none of its
        children is live, its edge becomes dormant (some expansion regressed) or dead (all
        collided), and the same question passes to its parent (the recession of Fig. 4)."""
        self.candidate[i] = False
        while i >= 0:
            kids = self.children[i]
            if self.candidate[i] or any(self.state[k] in (EdgeState.UNTRIED, EdgeState.LIVE) for k in kids):
                return
            if i > 0 and self.expansions[i] < max_expansions:
                return
            regressed = self.dormant_hits[i] > 0 or any(self.state[k] == EdgeState.DORMANT for k in kids)
            self.state[i] = EdgeState.DORMANT if regressed else EdgeState.DEAD
            i = int(self.parent[i])


def rrt_blossom(
    a: np.ndarray,
    b: np.ndarray,
    validator: MotionValidator,
    rng: np.random.Generator,
    deadline: float,
    *,
    config: BlossomConfig = BlossomConfig(),
    free_joints: np.ndarray | None = None,
    max_iterations: int | None = None,
) -> BlossomOutcome:
    """Search a legal path from state ``a`` to state ``b`` (both assumed legal).

    Args:
        a, b: states [p, q, V], shape (7 + n,).
        validator: FAILURE of Fig. 2 (and the checker's looseness).
        rng: the only source of randomness.
        deadline: ``time.monotonic()`` value at which to give up.
        config: knobs.
        free_joints: bool mask shape (n,) of joints that explore (partial-body planning); None
            for full-body planning (root and all joints).
        max_iterations: give up after this many iterations (None: only the deadline and the
            node limit stop the search). Unlike the deadline, it does not depend on the
            machine's speed, so what happens after a search that gave up stays deterministic.

    Returns:
        BlossomOutcome with the path (first row ``a``, last ``b``) or the reason.
    """
    t0 = time.monotonic()
    space = validator.space
    checks0 = validator.n_checks
    cfg = config
    n = space.n_joints
    partial = free_joints is not None
    free = np.ones(n, dtype=bool) if free_joints is None else np.asarray(free_joints, dtype=bool)

    def stats(trees: tuple[Tree, Tree], it: int) -> dict[str, float]:
        out: dict[str, float] = {"iterations": it, "seconds": time.monotonic() - t0, "checks": validator.n_checks - checks0}
        for name, tr in zip(("start", "goal"), trees):
            st = tr.state[: tr.n]
            out[f"nodes_{name}"] = tr.n
            out[f"dormant_{name}"] = int(np.sum(st == EdgeState.DORMANT))
            out[f"dead_{name}"] = int(np.sum(st == EdgeState.DEAD))
            out[f"untried_{name}"] = int(np.sum(st == EdgeState.UNTRIED))
            out[f"live_{name}"] = int(np.sum(st == EdgeState.LIVE))
        return out

    if validator.segment_valid(a, b):  # the straight motion is the trivial tree connection
        return BlossomOutcome(np.stack([a, b]), stats=stats((Tree(a, 2), Tree(b, 2)), 0))

    ta, tb = Tree(a, cfg.max_nodes), Tree(b, cfg.max_nodes)
    start_tree = ta
    span = np.where(free, cfg.span_rad, 0.0)

    lo_box = np.minimum(a[:3], b[:3]) - np.array([cfg.uniform_box_m[0], cfg.uniform_box_m[0], 0.25 * cfg.sample_position_m])
    hi_box = np.maximum(a[:3], b[:3]) + np.array([cfg.uniform_box_m[0], cfg.uniform_box_m[0], cfg.uniform_box_m[1]])

    def sample(toward: np.ndarray) -> np.ndarray:
        if rng.random() < cfg.goal_bias:
            return toward.copy()
        if rng.random() < cfg.uniform_share:
            x = np.concatenate([rng.uniform(lo_box, hi_box), uniform_quaternion(rng), rng.uniform(space.lower, space.upper)])
            if partial:  # partial-body: only the free joints explore
                base = space.interpolate(a, b, np.array([rng.random()]))[0]
                x[:7] = base[:7]
                x[7:] = np.where(free, x[7:], base[7:])
            return x
        s = rng.random()
        base = space.interpolate(a, b, np.array([s]))[0]
        x = base.copy()
        if not partial:
            r = cfg.sample_position_m
            x[:3] += rng.uniform([-r, -r, -0.25 * r], [r, r, r])  # biased up: lying postures touch the ground
            x[3:7] = space.rotate(x[3:7], rng.normal(size=3) * cfg.sample_orientation_rad / np.sqrt(3))
        if rng.random() < 0.5:
            v = rng.uniform(space.lower, space.upper)
        else:
            v = np.clip(base[7:] + rng.normal(scale=0.5, size=n), space.lower, space.upper)
        x[7:] = np.where(free, v, base[7:])
        return x

    def extend(tree: Tree, target: np.ndarray) -> int:
        """EXTEND_BLOSSOM of Fig. 2; returns the new node nearest the target or -1."""
        cand = np.flatnonzero(tree.candidate[: tree.n])
        if cand.size == 0:
            return -1
        d = space.distance(tree.x[cand], target)
        near = int(cand[np.argmin(d)])
        xn = tree.x[near]
        tree.expansions[near] += 1
        if tree.state[near] == EdgeState.UNTRIED:
            tree.state[near] = EdgeState.LIVE  # tried: it stays live until close() says otherwise
        main = space.step_toward(xn, target, cfg.step_position_m, cfg.step_orientation_rad, cfg.step_joint_rad)
        kids = [main]
        moving_v = np.abs(main[7:] - xn[7:]) > 0  # the joint part is still being planned
        moving_q = space.part_distances(main, xn)[1] > 0
        for _ in range(cfg.n_children):
            c = main.copy()
            if moving_v.any():
                c[7:] = np.clip(c[7:] + rng.uniform(-1.0, 1.0, n) * span, space.lower, space.upper)
            if moving_q and not partial:
                c[3:7] = space.rotate(c[3:7], rng.normal(size=3) * cfg.step_orientation_rad)
            kids.append(c)
        best, best_d = -1, np.inf
        dead = dormant = 0
        for c in kids:
            d_parent = float(space.distance(xn, c))
            if d_parent < 1e-9:
                continue
            if not validator.segment_valid(xn, c):  # FAILURE
                dead += 1
                continue
            d_tree = space.distance(tree.x[: tree.n], c)
            d_tree[near] = np.inf
            if d_tree.min() < d_parent:  # REGRESSION
                dormant += 1
                continue
            if tree.n >= tree.cap:
                break
            i = tree.add(c, near)
            dt = float(space.distance(c, target))
            if dt < best_d:
                best, best_d = i, dt
        tree.dormant_hits[near] += dormant
        tree.dead_hits[near] += dead
        if tree.expansions[near] >= (cfg.max_expansions if near > 0 else cfg.root_expansions):
            tree.close(near, cfg.max_expansions)
        return best

    def join(t1: Tree, i1: int, t2: Tree, i2: int) -> np.ndarray:
        """Path start -> goal through node i1 of t1 and node i2 of t2 (one of them the start tree)."""
        (ts, i_s), (tg, i_g) = ((t1, i1), (t2, i2)) if t1 is start_tree else ((t2, i2), (t1, i1))
        return np.concatenate([ts.x[ts.branch(i_s)], tg.x[tg.branch(i_g)][::-1]])

    it = 0
    while True:
        if time.monotonic() >= deadline:
            return BlossomOutcome(None, f"time budget ran out after {it} iterations", True, stats((ta, tb), it))
        if not ta.candidate[: ta.n].any() or not tb.candidate[: tb.n].any():
            which = "start" if not start_tree.candidate[: start_tree.n].any() else "goal"
            return BlossomOutcome(
                None,
                f"the {which} tree is exhausted: every expansion collides (dead) or regresses (dormant)",
                False,
                stats((ta, tb), it),
            )
        if max_iterations is not None and it >= max_iterations:
            return BlossomOutcome(None, f"iteration limit {max_iterations} reached", False, stats((ta, tb), it))
        if ta.n >= ta.cap - cfg.n_children - 1 or tb.n >= tb.cap - cfg.n_children - 1:
            return BlossomOutcome(None, f"node limit {cfg.max_nodes} reached", False, stats((ta, tb), it))
        it += 1
        x_rand = sample(tb.x[0])
        ia = extend(ta, x_rand)
        if ia >= 0:
            xa = ta.x[ia]
            last_d = np.inf
            for _ in range(cfg.connect_steps):
                ib = extend(tb, xa)
                if ib < 0:
                    break
                d = float(space.distance(tb.x[ib], xa))
                if d < cfg.connect_distance and validator.segment_valid(tb.x[ib], xa, check_end=False):
                    path = join(ta, ia, tb, ib)
                    return BlossomOutcome(path, stats=stats((ta, tb), it))
                if d >= last_d or time.monotonic() >= deadline:
                    break
                last_d = d
        ta, tb = tb, ta
