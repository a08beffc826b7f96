"""Benchmark of the energy-driven planner (paper 004) beside RRT-blossom and RRT-Connect.

Problems where the straight interpolation penetrates (issue 7, "Measured"):

- ``crossed_arms``: lying supine, forearms folded across the chest, left over right -> right over left;
- ``crossed_legs``: lying supine, legs crossed with the left over the right -> the right over the left;
- ``arm_under_back``: supine with the left arm under the back -> a sitting posture (torso upright,
  hips flexed 90 degrees, legs straight on the ground, hands forward) standing in for a library
  connecting posture (no library yet).

Each kind has ``n`` variants: the base pair with seeded joint jitter (the same jitter on both
ends), kept only when both ends are legal and the straight motion between them is not.

Planners compared on the same strict ``ValidityChecker``:

- ``energy``: ``plan_energy`` (this issue);
- ``rrt_blossom``: ``RRTBlossomPlanner`` of the other planner (issue 5), when importable;
- ``rrt_connect``: OMPL's RRT-Connect (PyPI ``ompl``) over root position, root rotation vector
  (relative to the start orientation) and joints, with the same checker as state validity and a
  motion resolution; our own RRT-Connect (``own_rrt_connect``) when ``ompl`` is absent.

Every solved path goes through the shared smoothing and timing (``plan_trajectory``) and is
measured: success, planning time, path length (paper 000 eq. 1 metric, ``path_length``), minimum
self clearance, and integrated squared jerk of the timed joint rows.

Run: ``python -m robot_rise.planning.bench_energy --n 10 --budget 30`` (prints a Markdown table).
"""

from __future__ import annotations

import argparse
import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from robot_rise.model import Robot, load_robot
from robot_rise.planning.energy import EnergyPlanner, segment_is_valid, tangent_difference, tangent_step
from robot_rise.planning.problem import PlanningProblem, PlanResult, PlanStatus, PostureSequence
from robot_rise.posture import Posture, posture_from_qpos
from robot_rise.validity import ValidityChecker

__all__ = [
    "CrossedProblem",
    "PROBLEM_KINDS",
    "supine_quat_wxyz",
    "crossed_problems",
    "straight_motion_is_illegal",
    "OmplRRTConnect",
    "OwnRRTConnect",
    "integrated_squared_jerk",
    "BenchRow",
    "run_benchmark",
    "main",
]

log = logging.getLogger(__name__)

PROBLEM_KINDS = ("crossed_arms", "crossed_legs", "arm_under_back")
JITTER_RAD = 0.05  # ours: per-joint jitter of the variants (same on both ends)
GROUND_GAP_M = 0.0005  # lying postures rest this far above the ground


@dataclass(frozen=True)
class CrossedProblem:
    """One benchmark problem: a kind, a variant number and the two postures."""

    kind: str
    variant: int
    start: Posture
    goal: Posture


def supine_quat_wxyz() -> np.ndarray:
    """Root orientation lying on the back: the torso's +x (front) up, head toward world -x."""
    a = -math.pi / 2
    return np.array([math.cos(a / 2), 0.0, math.sin(a / 2), 0.0])


def _posture(robot: Robot, checker: ValidityChecker, quat: np.ndarray, joints: dict[str, float], jitter: np.ndarray) -> Posture:
    """A posture resting on the ground (lowest point GROUND_GAP_M above z = 0)."""
    q = np.zeros(robot.n_joints)
    for name, v in joints.items():
        q[robot.joint_index(name)] = v
    q = np.clip(q + jitter, robot.joint_lower, robot.joint_upper)
    p = Posture(robot.name, np.array([0.0, 0.0, 0.3]), quat, dict(zip(robot.joint_names, q)))
    z = checker.lowest_point_z(checker.qpos_of(p))
    return p.with_root(root_pos=np.array([0.0, 0.0, 0.3 - z + GROUND_GAP_M]))


def _base_pairs() -> dict[str, tuple[tuple[np.ndarray, dict[str, float]], tuple[np.ndarray, dict[str, float]]]]:
    """Start and goal (orientation, joints) of each kind; joint names of the OP3-class robot's MJCF."""
    d = math.radians
    sup = supine_quat_wxyz()
    upright = np.array([1.0, 0.0, 0.0, 0.0])
    arms_common = {"l_sho_roll": d(90), "r_sho_roll": -d(90), "l_el": -d(85), "r_el": d(85)}

    def legs(left_over: bool) -> dict[str, float]:
        up, down = ("l", "r") if left_over else ("r", "l")
        flex = {"l": -1.0, "r": 1.0}  # sign of hip flexion per side
        add = {"l": 1.0, "r": -1.0}  # sign of hip adduction per side
        return {
            f"{up}_hip_pitch": flex[up] * d(35),
            f"{down}_hip_pitch": flex[down] * d(5),
            f"{up}_hip_roll": add[up] * 0.4,
            f"{down}_hip_roll": add[down] * 0.4,
        }

    return {
        "crossed_arms": (
            (sup, {**arms_common, "l_sho_pitch": -d(105), "r_sho_pitch": d(75)}),
            (sup, {**arms_common, "l_sho_pitch": -d(75), "r_sho_pitch": d(105)}),
        ),
        "crossed_legs": ((sup, legs(True)), (sup, legs(False))),
        "arm_under_back": (
            (sup, {"l_sho_pitch": d(90), "l_sho_roll": d(85), "l_el": -d(80), "r_sho_roll": -d(80)}),
            (
                upright,
                {
                    "l_hip_pitch": -d(90),
                    "r_hip_pitch": d(90),
                    "l_sho_pitch": -d(30),
                    "r_sho_pitch": d(30),
                    "l_sho_roll": d(70),
                    "r_sho_roll": -d(70),
                    "l_el": -d(10),
                    "r_el": d(10),
                },
            ),
        ),
    }


def straight_motion_is_illegal(checker: ValidityChecker, a: Posture, b: Posture) -> bool:
    """True when the straight (lerp / slerp) motion a -> b is illegal somewhere (5 mm resolution)."""
    return not segment_is_valid(checker, checker.qpos_of(a), checker.qpos_of(b))


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


# --- RRT-Connect baselines ------------------------------------------------------------------------


def _rotvec_to_quat(v: np.ndarray) -> np.ndarray:
    angle = float(np.linalg.norm(v))
    if angle < 1e-12:
        return np.array([1.0, 0.0, 0.0, 0.0])
    axis = v / angle
    return np.concatenate([[math.cos(angle / 2)], math.sin(angle / 2) * axis])


class _FlatSpace:
    """Flat coordinates for the RRT baselines: x = [root position (3), tangent rotation (3), joints (n)].

    The rotation part is the root-frame rotation vector from the start orientation (mujoco's
    tangent space), so a straight line in x is a straight tangent motion from the start.
    """

    def __init__(self, checker: ValidityChecker, start_qpos: np.ndarray) -> None:
        self.checker = checker
        self.m = checker.model
        self.q0 = np.array(start_qpos, dtype=float)
        self.idx = checker.index
        n = len(checker.robot.joint_names)
        self.dim = 6 + n
        self.low = np.concatenate([self.q0[self.idx.qpos_root[:3]] - 0.3, [-math.pi] * 3, checker.robot.joint_lower])
        self.high = np.concatenate([self.q0[self.idx.qpos_root[:3]] + 0.3, [math.pi] * 3, checker.robot.joint_upper])

    def qpos(self, x: np.ndarray) -> np.ndarray:
        q = self.q0.copy()
        q[self.idx.qpos_root[:3]] = x[:3]
        rot = np.zeros(4)
        base = self.q0[self.idx.qpos_root[3:]]
        import mujoco

        mujoco.mju_mulQuat(rot, base, _rotvec_to_quat(np.asarray(x[3:6])))
        q[self.idx.qpos_root[3:]] = rot
        q[self.idx.qpos_joints] = x[6:]
        return q

    def x(self, qpos: np.ndarray) -> np.ndarray:
        v = tangent_difference(self.m, self.q0, qpos)
        return np.concatenate([qpos[self.idx.qpos_root[:3]], v[self.idx.qvel_root[3:]], qpos[self.idx.qpos_joints]])

    def valid(self, x: np.ndarray) -> bool:
        return self.checker.is_valid_qpos(self.qpos(x))


def _result_from_xs(space: _FlatSpace, xs: list[np.ndarray], stats: dict) -> PlanResult:
    checker = space.checker
    postures = [posture_from_qpos(checker.robot, checker.index, space.qpos(x)) for x in xs]
    return PlanResult(PlanStatus.EXACT_SOLUTION, PostureSequence.from_postures(postures, checker.robot.joint_names), "", stats)


@dataclass(frozen=True)
class OmplRRTConnect:
    """OMPL's RRT-Connect (PyPI ``ompl``) on the strict checker, as a ``Planner``.

    Attributes:
        resolution: OMPL's longest valid segment fraction of the state-space extent.
        simplify: let OMPL shortcut the path (our smoothing runs afterwards anyway).
    """

    resolution: float = 0.002
    simplify: bool = False

    def __call__(self, problem: PlanningProblem) -> PlanResult:
        from ompl import base as ob  # optional dependency
        from ompl import geometric as og

        t0 = time.monotonic()
        checker = problem.checker
        qs, qg = checker.qpos_of(problem.start), checker.qpos_of(problem.goal)
        space = _FlatSpace(checker, qs)
        ss_space = ob.RealVectorStateSpace(space.dim)
        bounds = ob.RealVectorBounds(space.dim)
        for i in range(space.dim):
            bounds.setLow(i, float(space.low[i]))
            bounds.setHigh(i, float(space.high[i]))
        ss_space.setBounds(bounds)
        ss = og.SimpleSetup(ss_space)
        ss.setStateValidityChecker(lambda s: space.valid(np.array([s[i] for i in range(space.dim)])))
        ss.getSpaceInformation().setStateValidityCheckingResolution(self.resolution)
        start, goal = ob.State(ss_space), ob.State(ss_space)
        for i, (a, b) in enumerate(zip(space.x(qs), space.x(qg))):
            start[i] = float(a)
            goal[i] = float(b)
        ss.setStartAndGoalStates(start, goal)
        planner = og.RRTConnect(ss.getSpaceInformation())
        ss.setPlanner(planner)
        solved = ss.solve(float(problem.budget_s))
        stats = {"planner": "ompl RRTConnect", "seconds": time.monotonic() - t0}
        if not solved or not ss.haveExactSolutionPath():
            return PlanResult(PlanStatus.TIMEOUT, None, f"OMPL RRT-Connect found no exact path in {problem.budget_s:.0f} s", stats)
        if self.simplify:
            ss.simplifySolution()
        path = ss.getSolutionPath()
        xs = [np.array([path.getState(k)[i] for i in range(space.dim)]) for k in range(path.getStateCount())]
        stats["seconds"] = time.monotonic() - t0
        return _result_from_xs(space, xs, stats)


@dataclass(frozen=True)
class OwnRRTConnect:
    """Our RRT-Connect (Kuffner & LaValle 2000) on the strict checker, used when ``ompl`` is absent.

    Attributes:
        step: extension step in flat coordinates (max-norm) [rad or m].
        edge_resolution_m: travel resolution of edge checks [m].
    """

    step: float = 0.15
    edge_resolution_m: float = 0.01

    def __call__(self, problem: PlanningProblem) -> PlanResult:
        t0 = time.monotonic()
        checker = problem.checker
        qs, qg = checker.qpos_of(problem.start), checker.qpos_of(problem.goal)
        space = _FlatSpace(checker, qs)
        rng = np.random.default_rng(problem.seed)
        trees = [([space.x(qs)], [-1]), ([space.x(qg)], [-1])]

        def edge_ok(a: np.ndarray, b: np.ndarray) -> bool:
            return segment_is_valid(checker, space.qpos(a), space.qpos(b), resolution_m=self.edge_resolution_m)

        def extend(tree, target) -> tuple[str, int]:
            nodes, parents = tree
            arr = np.array(nodes)
            near = int(np.argmin(np.max(np.abs(arr - target), axis=1)))
            d = target - arr[near]
            dist = float(np.max(np.abs(d)))
            new = target if dist <= self.step else arr[near] + d * (self.step / dist)
            if not space.valid(new) or not edge_ok(arr[near], new):
                return "trapped", -1
            nodes.append(new)
            parents.append(near)
            return ("reached" if dist <= self.step else "advanced"), len(nodes) - 1

        it = 0
        while time.monotonic() - t0 < problem.budget_s:
            it += 1
            target = rng.uniform(space.low, space.high)
            a, b = trees[it % 2], trees[(it + 1) % 2]
            status, ka = extend(a, target)
            if status == "trapped":
                continue
            while True:
                status_b, kb = extend(b, a[0][ka])
                if status_b != "advanced":
                    break
            if status_b == "reached":
                def chain(tree, k):
                    out = []
                    while k >= 0:
                        out.append(tree[0][k])
                        k = tree[1][k]
                    return out[::-1]

                pa, pb = chain(a, ka), chain(b, kb)
                xs = pa + pb[::-1][1:] if a is trees[0] else pb + pa[::-1][1:]
                stats = {"planner": "own RRTConnect", "iterations": it, "seconds": time.monotonic() - t0}
                return _result_from_xs(space, xs, stats)
        return PlanResult(PlanStatus.TIMEOUT, None, f"own RRT-Connect found no path in {problem.budget_s:.0f} s", {"iterations": it})


def rrt_connect_planner() -> tuple[str, Callable[[PlanningProblem], PlanResult]]:
    """OMPL's RRT-Connect when the ``ompl`` package imports, else ours; with its label."""
    try:  # the PyPI ompl 2.x (nanobind) bindings do not expose ob.State(space) like 1.x did
        from ompl import base as ob

        ob.State(ob.RealVectorStateSpace(2))
        return "rrt_connect (ompl)", OmplRRTConnect()
    except Exception as e:
        log.warning("ompl RRT-Connect unusable (%s); using our own RRT-Connect", e)
        return "rrt_connect (own)", OwnRRTConnect()


# --- measurement ----------------------------------------------------------------------------------


def integrated_squared_jerk(t: np.ndarray, q: np.ndarray) -> float:
    """Sum over joints of the integral of the squared third derivative [rad^2 / s^5].

    Args:
        t: sample times [s], shape (T,), uniform period.
        q: joint angles [rad], shape (T, n).
    """
    if len(t) < 4:
        return 0.0
    dt = float(np.median(np.diff(t)))
    jerk = np.diff(q, n=3, axis=0) / dt**3
    return float(np.sum(jerk * jerk) * dt)


@dataclass(frozen=True)
class BenchRow:
    """One planner on one problem."""

    planner: str
    kind: str
    variant: int
    solved: bool
    plan_s: float
    path_length: float
    min_self_clearance_m: float
    jerk: float
    duration_s: float
    reason: str


def _planners(budget_s: float) -> list[tuple[str, Callable[[PlanningProblem], PlanResult]]]:
    out: list[tuple[str, Callable[[PlanningProblem], PlanResult]]] = [("energy", EnergyPlanner())]
    try:
        from robot_rise.planning.refine import RRTBlossomPlanner

        out.append(("rrt_blossom", RRTBlossomPlanner()))
    except ImportError as e:  # the other planner is not there
        log.warning("RRT-blossom not importable (%s); skipped", e)
    out.append(rrt_connect_planner())
    return out


def run_benchmark(*, n: int = 5, budget_s: float = 30.0, seed: int = 0, planners: list[str] | None = None, kinds: tuple[str, ...] = PROBLEM_KINDS) -> list[BenchRow]:
    """Every planner on every problem; smoothing and timing through ``plan_trajectory``."""
    from robot_rise.planning.to_trajectory import path_length, path_min_clearance, plan_trajectory

    robot = load_robot()
    checker = ValidityChecker(robot, "flat")
    problems = crossed_problems(robot, checker, kinds=kinds, n=n, seed=seed)
    rows: list[BenchRow] = []
    for name, planner in _planners(budget_s):
        if planners and not any(name.startswith(p) for p in planners):
            continue
        for pr in problems:
            problem = PlanningProblem(pr.start, pr.goal, checker, budget_s=budget_s, seed=seed + pr.variant)
            t0 = time.monotonic()
            try:
                out = plan_trajectory(problem, planner=planner)
            except Exception as e:  # a baseline crashing is a failure of that run, not of the benchmark
                log.exception("%s on %s/%d raised", name, pr.kind, pr.variant)
                rows.append(BenchRow(name, pr.kind, pr.variant, False, time.monotonic() - t0, math.nan, math.nan, math.nan, math.nan, repr(e)))
                continue
            plan_s = out.seconds.get("plan", math.nan)
            if not out.solved or out.trajectory is None or out.smoothed is None:
                rows.append(BenchRow(name, pr.kind, pr.variant, False, plan_s, math.nan, math.nan, math.nan, math.nan, out.result.reason))
                continue
            traj = out.trajectory
            clear = path_min_clearance(out.smoothed, checker)
            rows.append(
                BenchRow(
                    name,
                    pr.kind,
                    pr.variant,
                    True,
                    plan_s,
                    path_length(out.smoothed, checker),
                    clear["self"],
                    integrated_squared_jerk(traj.t, traj.q),
                    float(traj.t[-1]),
                    "",
                )
            )
            log.info("%s %s/%d: %s in %.2f s", name, pr.kind, pr.variant, "solved" if rows[-1].solved else "failed", plan_s)
    return rows


def summary_table(rows: list[BenchRow]) -> str:
    """Markdown table per planner and kind: success, median/p95 plan time, length, clearance, jerk."""
    lines = [
        "| planner | problem | success | plan time median / p95 [s] | path length median | min self clearance [mm] | integrated sq. jerk median [rad²/s⁵] | duration median [s] |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    keys = []
    for r in rows:
        if (r.planner, r.kind) not in keys:
            keys.append((r.planner, r.kind))
    for planner, kind in keys:
        rs = [r for r in rows if r.planner == planner and r.kind == kind]
        ok = [r for r in rs if r.solved]
        times = np.array([r.plan_s for r in rs if r.solved])

        def med(vals: list[float]) -> str:
            return f"{np.median(vals):.3g}" if vals else "-"

        t_txt = f"{np.median(times):.2f} / {np.percentile(times, 95):.2f}" if len(times) else "-"
        clear = f"{1000 * min(r.min_self_clearance_m for r in ok):.1f}" if ok else "-"
        lines.append(
            f"| {planner} | {kind} | {len(ok)}/{len(rs)} | {t_txt} | {med([r.path_length for r in ok])} | {clear} | "
            f"{med([r.jerk for r in ok])} | {med([r.duration_s for r in ok])} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Command line: run the benchmark and print the Markdown table (and failures)."""
    ap = argparse.ArgumentParser(description="Energy planner benchmark (paper 004) beside RRT-blossom and RRT-Connect.")
    ap.add_argument("--n", type=int, default=5, help="variants per problem kind")
    ap.add_argument("--budget", type=float, default=30.0, help="planning budget per run [s]")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--planners", nargs="*", default=None, help="prefixes: energy rrt_blossom rrt_connect")
    ap.add_argument("--kinds", nargs="*", default=list(PROBLEM_KINDS), choices=PROBLEM_KINDS)
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    rows = run_benchmark(n=args.n, budget_s=args.budget, seed=args.seed, planners=args.planners, kinds=tuple(args.kinds))
    print(summary_table(rows))
    for r in rows:
        if not r.solved:
            print(f"- {r.planner} {r.kind}/{r.variant}: {r.reason[:200]}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
