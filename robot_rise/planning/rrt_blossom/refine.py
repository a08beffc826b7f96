"""The planner of paper 000 section 4.2: RRT-blossom with loose-to-strict local refinement.

1. Loose (section 4.2.3): the ground is lowered to the lowest body point of the two end
   postures and every obstacle shrunk to (almost) zero; RRT-blossom plans the whole path.
2. Strict, step by step: the ground rises and the obstacles grow by LOOSE_TO_STRICT_INCREMENT_M
   (0.025) per iteration until they reach their real values. At each iteration the path is
   checked; only its illegal segments are cut out and replanned (cut and merge, section 4.2.4;
   runs of illegal edges less than ``merge_gap`` waypoints apart are merged and replanned as
   one).
3. A segment colliding with the ground or breaking a limit is replanned full-body; a segment
   with only self or obstacle collisions is first replanned partial-body (only the joints of the
   limbs in collision explore; the rest of the body and the root follow the straight motion
   between the segment's ends), and full-body if that fails.
4. The finished path is re-verified at VERIFY_RESOLUTION_M (finer than the planning
   resolution) and repaired the same way where needed.

With a key posture the legs start -> key and key -> goal are planned in turn (paper 000
section 4: the key posture is passed through, then the connecting posture).

An expected failure is a PlanResult status with the reason: which leg, which iteration of the
refinement, which segment, which constraint, and what the search ran into.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from robot_rise.constants import EDGE_RESOLUTION_M, LOOSE_TO_STRICT_INCREMENT_M, VERIFY_RESOLUTION_M
from robot_rise.model import Robot
from robot_rise.planning.motion_validator import MotionValidator
from robot_rise.planning.problem import PlanningProblem, PlanResult, PlanStatus, PostureSequence
from robot_rise.planning.rrt_blossom.search import BlossomConfig, rrt_blossom
from robot_rise.planning.space import PostureSpace
from robot_rise.posture import validate_posture
from robot_rise.validity import Looseness, ValidityChecker, ValidityReport

__all__ = ["illegal_edge_runs", "PlannerConfig", "RRTBlossomPlanner", "loose_to_strict_schedule", "limbs_of_collisions", "states_to_sequence"]

log = logging.getLogger(__name__)

PARTIAL_BODY_MAX_ITERATIONS = 300  # ours; see PlannerConfig.partial_max_iterations and BENCHMARKS.md


@dataclass(frozen=True)
class PlannerConfig:
    """Knobs of the refinement around RRT-blossom.

    Attributes:
        blossom: RRT-blossom knobs.
        resolution_m: edge checking resolution while planning [m] (robot-point travel).
        verify_resolution_m: resolution of the final verification [m].
        increment_m: loose-to-strict step of ground height and obstacle size [m] (000 4.2.3).
        merge_gap: illegal runs fewer than this many waypoints apart are replanned as one.
        partial_body: try partial-body replanning for self/obstacle collisions first.
        partial_share: share of the remaining budget a partial-body attempt may use.
        partial_max_iterations: RRT-blossom iterations of a partial-body attempt before the
            segment is replanned full-body (an attempt that cannot succeed, e.g. the head alone
            against a beam, otherwise spends ``partial_share`` of the budget; iterations rather
            than seconds keep the following full-body search deterministic for a seed).
        max_repair_rounds: check-and-repair rounds per refinement iteration.
    """

    blossom: BlossomConfig = BlossomConfig()
    resolution_m: float = EDGE_RESOLUTION_M
    verify_resolution_m: float = VERIFY_RESOLUTION_M
    increment_m: float = LOOSE_TO_STRICT_INCREMENT_M
    merge_gap: int = 2
    partial_body: bool = True
    partial_share: float = 0.3
    partial_max_iterations: int = PARTIAL_BODY_MAX_ITERATIONS
    max_repair_rounds: int = 4


def loose_to_strict_schedule(checker: ValidityChecker, ends_qpos: list[np.ndarray], increment_m: float) -> list[Looseness]:
    """Looseness per refinement iteration, from loosest to STRICT (last).

    Ground: lowered to the lowest robot point of the end postures (0 when they rest on it).
    Obstacles: shrunk by their largest half-size, i.e. to zero; both tighten by ``increment_m``.
    """
    low = min(checker.lowest_point_z(q) for q in ends_qpos)
    ground_z = max((float(checker.model.geom_pos[g, 2]) for g in checker.index.ground_geoms), default=0.0)
    drop0 = max(0.0, ground_z - low - checker.contact_tolerance_m)
    sizes = [float(np.max(checker.model.geom_size[g])) for g in checker.index.obstacle_geoms]
    shrink0 = max(sizes, default=0.0)
    n = math.ceil(max(drop0, shrink0) / increment_m - 1e-9)
    out = [Looseness(max(0.0, drop0 - k * increment_m), max(0.0, shrink0 - k * increment_m)) for k in range(n)]
    return [*out, Looseness()]


def limbs_of_collisions(robot: Robot, checker: ValidityChecker, report: ValidityReport) -> tuple[str, ...] | None:
    """Limbs (robot.limbs names) whose geoms take part in the report's self/obstacle collisions.

    Returns None when partial-body planning does not apply: a ground collision, a limit
    violation, or a collision of a geom moved by no limb joint (the trunk).
    """
    if report.limit_violations or report.ground_penetration or not robot.limbs:
        return None
    m = checker.model
    joint_limb = {j: name for name, joints in robot.limbs.items() for j in joints}
    robot_geoms = set(int(g) for g in checker.index.robot_geoms)
    limbs: set[str] = set()
    for c in report.collisions:
        for gname in (c.geom1, c.geom2):
            g = m.geom(gname).id
            if g not in robot_geoms:
                continue
            body = int(m.geom_bodyid[g])
            limb = None
            while body > 0 and limb is None:
                for j in range(int(m.body_jntadr[body]), int(m.body_jntadr[body]) + int(m.body_jntnum[body])):
                    limb = joint_limb.get(m.joint(j).name, limb)
                body = int(m.body_parentid[body])
            if limb is None:
                return None
            limbs.add(limb)
    return tuple(sorted(limbs)) or None


def states_to_sequence(space: PostureSpace, states: np.ndarray) -> PostureSequence:
    """States (K, 7 + n) -> PostureSequence."""
    states = np.asarray(states, dtype=float)
    quat = states[:, 3:7] / np.linalg.norm(states[:, 3:7], axis=1, keepdims=True)
    return PostureSequence(space.robot_name, space.joint_names, states[:, :3].copy(), quat, states[:, 7:].copy())


class _Failure(Exception):
    def __init__(self, status: PlanStatus, reason: str) -> None:
        super().__init__(reason)
        self.status = status
        self.reason = reason


def illegal_edge_runs(bad: np.ndarray, gap: int) -> list[tuple[int, int]]:
    """Merged runs of illegal edges as (first waypoint, last waypoint) pairs of legal ends."""
    idx = np.flatnonzero(bad)
    runs: list[list[int]] = []
    for e in idx:
        if runs and e - runs[-1][1] < gap:
            runs[-1][1] = int(e) + 1
        else:
            runs.append([int(e), int(e) + 1])
    return [(a, b) for a, b in runs]


def _blocked(v: MotionValidator, a: np.ndarray, b: np.ndarray) -> str:
    """What blocks the straight motion a -> b (the constraint the search had to get round)."""
    seg = v.first_invalid(a, b)
    if seg.valid or seg.report is None:
        return "the straight motion is legal"
    return f"the straight motion is first illegal at {100 * (seg.first_invalid_s or 0.0):.0f}% of the way: {'; '.join(seg.report.reasons())}"


def _describe(lo: Looseness) -> str:
    if lo.is_strict:
        return "strict (real ground and obstacles)"
    return f"ground lowered {lo.ground_drop_m * 1000:.0f} mm, obstacles shrunk {lo.obstacle_shrink_m * 1000:.0f} mm"


@dataclass
class Run:
    """Mutable state of one planning call."""

    robot: Robot
    space: PostureSpace
    cfg: PlannerConfig
    rng: np.random.Generator
    deadline: float
    stats: dict[str, Any] = field(default_factory=dict)

    def bump(self, key: str, by: float = 1) -> None:
        self.stats[key] = self.stats.get(key, 0) + by


class RRTBlossomPlanner:
    """Paper 000's planner as a ``Planner``: ``RRTBlossomPlanner(config)(problem) -> PlanResult``."""

    def __init__(self, config: PlannerConfig = PlannerConfig()) -> None:
        self.config = config

    def __call__(self, problem: PlanningProblem) -> PlanResult:
        """Plan; an expected failure is a status with its reason.

        Raises:
            PostureError: a posture is for another robot or lacks joints (bad input, not a failure).
        """
        t0 = time.monotonic()
        checker = problem.checker
        robot = checker.robot
        space = PostureSpace.for_robot(robot)
        run = Run(robot, space, self.config, np.random.default_rng(problem.seed), t0 + problem.budget_s)
        for label, p in (("start", problem.start), ("goal", problem.goal), ("key", problem.key)):
            if p is not None:
                validate_posture(p, robot, where=f"{label} posture")  # wrong robot or joints: an input error
        for label, p, status in (("start", problem.start, PlanStatus.INVALID_START), ("goal", problem.goal, PlanStatus.INVALID_GOAL)):
            rep = checker.check(p)
            if not rep.valid:
                return PlanResult(status, reason=f"{label} posture is invalid: {'; '.join(rep.reasons())}", stats={"seconds": time.monotonic() - t0})
        ends = [problem.start] + ([problem.key] if problem.key is not None else []) + [problem.goal]
        if problem.key is not None:
            rep = checker.check(problem.key)
            if not rep.valid:
                return PlanResult(PlanStatus.INVALID_GOAL, reason=f"key posture is invalid: {'; '.join(rep.reasons())}", stats={"seconds": time.monotonic() - t0})
        base = MotionValidator(checker, space, self.config.resolution_m)
        pieces: list[np.ndarray] = []
        try:
            for i in range(len(ends) - 1):
                names = ["start", "key"] if problem.key is not None and i == 0 else ["key" if problem.key is not None else "start", "goal"]
                leg = f"leg {names[0]} -> {names[1]}"
                path = self._plan_leg(run, base, space.state(ends[i]), space.state(ends[i + 1]), leg)
                pieces.append(path if not pieces else path[1:])
        except _Failure as f:
            run.stats["seconds"] = time.monotonic() - t0
            run.stats["checks"] = base.n_checks + run.stats.get("checks", 0)
            log.info("planning failed: %s", f.reason)
            return PlanResult(f.status, reason=f.reason, stats=run.stats)
        states = np.concatenate(pieces)
        run.stats["seconds"] = time.monotonic() - t0
        run.stats["waypoints"] = len(states)
        log.info("planned %d waypoints in %.3f s", len(states), run.stats["seconds"])
        return PlanResult(PlanStatus.EXACT_SOLUTION, path=states_to_sequence(space, states), stats=run.stats)

    # --- one leg -------------------------------------------------------------------------------

    def _plan_leg(self, run: Run, base: MotionValidator, a: np.ndarray, b: np.ndarray, leg: str) -> np.ndarray:
        cfg = self.config
        checker = base.checker
        schedule = loose_to_strict_schedule(checker, [base._qpos(a), base._qpos(b)], cfg.increment_m)
        run.stats["levels"] = max(run.stats.get("levels", 0), len(schedule))
        validators = [base.with_checker(checker if lo.is_strict else checker.loosened(lo)) for lo in schedule]
        v0 = validators[0]
        out = rrt_blossom(a, b, v0, run.rng, run.deadline, config=cfg.blossom)
        self._count(run, out.stats)
        run.bump("checks", v0.n_checks)
        if out.path is None:
            status = PlanStatus.TIMEOUT if out.timed_out else PlanStatus.FAILED
            raise _Failure(status, f"{leg}, refinement iteration 1/{len(schedule)} ({_describe(schedule[0])}): RRT-blossom found no path: {out.reason}; {_blocked(v0, a, b)}")
        path = out.path
        for k, (lo, v) in enumerate(zip(schedule, validators)):
            if k == 0:
                continue
            where = f"{leg}, refinement iteration {k + 1}/{len(schedule)} ({_describe(lo)})"
            path = self._repair(run, v, path, where)
            run.bump("checks", v.n_checks)
        fine = base.with_resolution(cfg.verify_resolution_m)
        path = self._repair(run, fine, path, f"{leg}, final verification at {cfg.verify_resolution_m * 1000:.1f} mm")
        run.bump("checks", fine.n_checks)
        return path

    def _repair(self, run: Run, v: MotionValidator, path: np.ndarray, where: str) -> np.ndarray:
        """Cut and merge: replan the illegal segments of ``path`` under validator ``v``."""
        for _ in range(self.config.max_repair_rounds):
            bad = v.illegal_edges(path)
            if not bad.any():
                return path
            runs = illegal_edge_runs(bad, self.config.merge_gap)
            for i, j in reversed(runs):  # from the end, so earlier indices stay put
                first = i + int(np.argmax(bad[i:j]))
                seg = v.first_invalid(path[first], path[first + 1])
                rep = seg.report
                sub = self._replan(run, v, path[i], path[j], rep, f"{where}: segment {i}-{j} of {len(path)} waypoints")
                path = np.concatenate([path[:i], sub, path[j + 1 :]])
        if v.illegal_edges(path).any():
            raise _Failure(PlanStatus.FAILED, f"{where}: still illegal after {self.config.max_repair_rounds} repair rounds")
        return path

    def _replan(self, run: Run, v: MotionValidator, a: np.ndarray, b: np.ndarray, rep: ValidityReport | None, where: str) -> np.ndarray:
        cfg = self.config
        what = "; ".join(rep.reasons()) if rep is not None else "illegal edge"
        run.bump("replans")
        limbs = limbs_of_collisions(run.robot, v.checker, rep) if (rep is not None and cfg.partial_body) else None
        if limbs:
            mask = np.array([any(j in run.robot.limbs[lb] for lb in limbs) for j in run.robot.joint_names])
            now = time.monotonic()
            dl = min(run.deadline, now + cfg.partial_share * max(0.0, run.deadline - now))
            out = rrt_blossom(a, b, v, run.rng, dl, config=cfg.blossom, free_joints=mask, max_iterations=cfg.partial_max_iterations)
            self._count(run, out.stats)
            run.bump("partial_body_iterations", out.stats.get("iterations", 0))
            if out.path is not None:
                run.bump("partial_body_replans")
                log.debug("%s: partial-body (%s) replanned (%s)", where, ", ".join(limbs), what)
                return out.path
        out = rrt_blossom(a, b, v, run.rng, run.deadline, config=cfg.blossom)
        self._count(run, out.stats)
        if out.path is None:
            status = PlanStatus.TIMEOUT if out.timed_out else PlanStatus.FAILED
            raise _Failure(status, f"{where} ({what}) could not be replanned: {out.reason}; {_blocked(v, a, b)}")
        run.bump("full_body_replans")
        log.debug("%s: full-body replanned (%s)", where, what)
        return out.path

    @staticmethod
    def _count(run: Run, s: dict[str, float]) -> None:
        run.bump("iterations", s.get("iterations", 0))
        run.bump("nodes", s.get("nodes_start", 0) + s.get("nodes_goal", 0))
        run.bump("dormant", s.get("dormant_start", 0) + s.get("dormant_goal", 0))
        run.bump("dead", s.get("dead_start", 0) + s.get("dead_goal", 0))
