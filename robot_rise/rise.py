"""The product's main job: from a lying posture to a proven get-up trajectory.

select (paper 000 section 4.1) -> plan (RRT-blossom, section 4.2) -> smooth and time -> join the
library motion -> dynamics filter (section 4.3) -> proof. When a candidate fails (no path within
the budget, or the filter cannot make it stand), the next-nearest library motion is tried; the
result lists every attempt and why it failed. When every candidate fails, the one the filter gave
up on while its torque peak was still coming down is filtered with ``MORE_ITERATIONS`` more; then
the robot rises again from where the failed attempt leaves it lying (the attempt cut short before
the torque bound where it goes over: ``robot_rise.filter.stopped_before_torque_bound``).
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from robot_rise.constants import APPROACH_OFF_PLAN_RAD
from robot_rise.errors import PostureError, RobotRiseError
from robot_rise.filter import (
    ARRIVAL_SETTLE_S,
    COMMAND_LIMITS_KEY,
    TAIL_MAX_STRETCH,
    PREDICTED_KEY,
    EnsembleReplayer,
    FilterConfig,
    FilterResult,
    NOISE_CHECK_KEY,
    Proof,
    command_limits_for,
    conform,
    dynamics_filter,
    gravity_angle_rad,
    join_with_blend,
    join_with_overlap,
    overlap_of,
    load_start_proof,
    noise_check,
    predicted_positions,
    prove,
    prove_composed,
    prove_start,
    save_start_proof,
    settled_start,
    start_proof_key,
    stopped_before_torque_bound,
    StartProof,
    stands_under,
    with_ensemble,
    with_noise,
)
from robot_rise.sim.player import Player, Recording
from robot_rise.sim.variants import ModelVariant
from robot_rise.library import (Connection, FrameIndex, KMeansTree, Motion, MotionLibrary, connecting_posture, connection_candidates, load_library,
                                lying_frames, robot_library_dir)
from robot_rise.model import Robot
from robot_rise.placement import MotionRoom, motion_room
from robot_rise.planning.problem import PlanningProblem
from robot_rise.planning.space import PostureSpace
from robot_rise.planning.timing import TimingLimits, time_parameterize
from robot_rise.planning.smoothing import QUICK_SMOOTHING, SmoothingConfig
from robot_rise.planning.to_trajectory import plan_trajectory, timed_to_trajectory
from robot_rise.posture import Posture, admit_posture
from robot_rise.trajectory import Trajectory
from robot_rise.sampling import classify_lying
from robot_rise.validity import Looseness, ValidityChecker
from robot_rise.seal import sealed

__all__ = [
    "MORE_ITERATIONS",
    "connection_room",
    "RiseAttempt",
    "RiseResult",
    "RiseContext",
    "rise",
    "GoalSelection",
    "select_goal",
]

log = logging.getLogger(__name__)

DEFAULT_CANDIDATES = 3  # library motions tried: the quickest, then the two nearest; one more after a motion with a timing window (connection_candidates)
DEFAULT_RETRIES = 1  # new rises from where a failed attempt left the robot lying
DEFAULT_CANDIDATE_RANK = "duration"  # the quickest expected get-up first, the nearest next (issue 17; connection_candidates)
RECOVERY_MAX_JOINT_SPEED = 0.5  # [rad/s] the robot must be at rest to count as lying there
RECOVERY_MAX_ROOT_SPEED = 0.2  # [m/s, rad/s combined norm]
OBSTACLES_ONLY_GROUND_DROP_M = 2.0  # the ground moved this far down: a checker that sees only obstacles [m]
MAX_STRETCH = 2.5  # FilterConfig.max_stretch of a rise (unless the caller sets one): a library motion slowed more is the next candidate's turn
KEY_IN_LIBRARY_DISTANCE = 1e-6  # a key posture this close (planner distance) to its connecting posture is that library posture
NOT_COMPOSABLE = "not joined by a composed proof: its start proof does not stand on every variant, or its nominal torque is not proven from every arrival-spread start"
# a candidate that stood and was only over the torque bound, still coming down when the filter's
# iterations ran out (by at least this much in its last one), is filtered again with this many more
# once no candidate is proven (Wolfgang-OP, a side start: an elbow under the 6.1 kg body came
# down 1.00 -> 0.99 -> 0.96 in iterations 4-6 as its approach was slowed; the bound is 0.88)
MORE_ITERATIONS = 6
MORE_ITERATIONS_MIN_DROP = 0.005
SAME_TARGETS_RAD = 1e-4  # [rad] a composed approach ending this close to the motion's first targets ends on them (rounding, far below one servo tick of 1.5 mrad): no 0.3 s step there


@dataclass(frozen=True)
class RiseAttempt:
    """One candidate tried: which motion and frame, and what became of it."""

    motion: str
    frame: int
    distance: float
    planned: bool
    plan_reason: str = ""
    proven: bool = False
    filter_reason: str = ""
    seconds: dict[str, float] = field(default_factory=dict)
    robust: bool = False
    blocked: str = ""  # why the motion has no room where it would go (placement.motion_room); nothing was planned
    skipped: str = ""  # why this pass does not try the motion (rise(composed=True): not composable); nothing was planned
    more_iterations: int = 0  # the candidate filtered again with this many more iterations (MORE_ITERATIONS)
    cautious: str = ""  # the fast approach went off plan, so the same path was filtered again cautiously timed: "proven" or why not

    def describe(self) -> str:
        if self.skipped:
            return f"{self.motion}@{self.frame}: skipped ({self.skipped})"
        if self.blocked:
            return f"{self.motion}@{self.frame}: {self.blocked}"
        if not self.planned:
            return f"{self.motion}@{self.frame}: no path ({self.plan_reason})"
        again = f" with {self.more_iterations} more filter iterations" if self.more_iterations else ""
        again += f" (off plan; cautiously timed: {self.cautious})" if self.cautious else ""
        if not self.proven:
            return f"{self.motion}@{self.frame}{again}: not proven ({self.filter_reason})"
        return f"{self.motion}@{self.frame}{again}: proven" + ("" if self.robust else ", not robust to model errors")


@dataclass(frozen=True)
class RiseResult:
    """Outcome of :func:`rise`. ``trajectory`` is set whenever a motion was filtered (even unproven).

    Attributes:
        proven: the trajectory stands, proven by the filter's replay (its ``proof``).
        trajectory: the servo targets from the start posture (None when nothing was filtered).
        attempts: every candidate tried, in order, with what became of it.
        reason: why not proven (empty when proven).
        filter_result: the filter's evidence for the returned trajectory.
    """

    proven: bool
    trajectory: Trajectory | None
    attempts: tuple[RiseAttempt, ...]
    reason: str = ""
    filter_result: FilterResult | None = None

    @property
    def proof(self) -> Proof | None:
        """The proof written in the trajectory's report (None when nothing was filtered)."""
        if self.trajectory is None or "proven" not in self.trajectory.report:
            return None
        return Proof.from_dict(self.trajectory.report)


@dataclass
class RiseContext:
    """What every rise of one robot in one scene reuses: checker, library, frame index, K-means tree.

    Build it once (``RiseContext.build``) when rising many times; ``rise`` builds one otherwise.
    """

    robot: Robot
    scene: str | os.PathLike[str] | None
    checker: ValidityChecker
    library: MotionLibrary
    index: FrameIndex
    tree: KMeansTree
    _obstacle_checker: ValidityChecker | None = field(default=None, repr=False)
    _ensemble: EnsembleReplayer | None = field(default=None, repr=False)
    _start_proofs: dict[tuple[str, FilterConfig], StartProof | None] = field(default_factory=dict, repr=False)

    def start_proof(self, motion: Motion, config: FilterConfig = FilterConfig()) -> StartProof | None:
        """The motion proven from rest on its first targets on every variant
        (:func:`robot_rise.filter.prove_start`), None where the nominal model does not prove it;
        read from the start proof cache (``robot_rise.filter.start_cache``) or computed on first
        use (``warm_start_proofs`` does all at once) and kept there, then reused."""
        # what a start proof rests on: the margins, noise and hold of the caller's config, the
        # motion's combined variants; not the stretch bounds of a get-up's nominal filter
        config = dataclasses.replace(_joining(config, motion), max_stretch=None, motion_max_stretch=None)
        if (motion.name, config) not in self._start_proofs:
            key = start_proof_key(self.robot, self.scene, motion.name, motion.trajectory, motion.start, config)
            kept = load_start_proof(key)
            if kept is None:
                rec, _, nominal = prove(self.robot, settled_start(motion.trajectory), scene=self.scene, config=config, start=motion.start)
                kept = prove_start(motion.name, motion.trajectory, self.ensemble(), config, rec) if nominal.proven else None
                if kept is not None:
                    save_start_proof(key, kept)
            self._start_proofs[motion.name, config] = kept
        return self._start_proofs[motion.name, config]

    def warm_start_proofs(self, config: FilterConfig = FilterConfig()) -> int:
        """Every library motion's start proof now (what a live get-up precomputes per robot); how many compose."""
        return sum(self.start_proof(m, config) is not None for m in self.library.motions)

    def ensemble(self) -> EnsembleReplayer:
        """The model variants' players in this scene (built on first use, then reused)."""
        if self._ensemble is None:
            self._ensemble = EnsembleReplayer(self.robot, self.scene)
        return self._ensemble

    def obstacle_checker(self) -> ValidityChecker | None:
        """The scene's obstacles without its ground (placement.motion_room), None without obstacles."""
        if self.checker.index.obstacle_geoms.size == 0:
            return None
        if self._obstacle_checker is None:
            self._obstacle_checker = ValidityChecker(self.robot, self.scene, looseness=Looseness(ground_drop_m=OBSTACLES_ONLY_GROUND_DROP_M))
        return self._obstacle_checker

    @classmethod
    def build(cls, robot: Robot, scene: str | os.PathLike[str] | None = "flat", library: MotionLibrary | None = None) -> RiseContext:
        library = library or load_library(robot_library_dir(robot))
        index = lying_frames(FrameIndex.build(library, robot), library)
        return cls(robot, scene, ValidityChecker(robot, scene), library, index, KMeansTree(index))


@dataclass(frozen=True)
class GoalSelection:
    """Where a plan goes when the user names no goal (``select_goal``).

    Attributes:
        goal: the connecting posture, placed where the robot lies (or where the key posture is).
        key: the key posture to pass through, or None (none given, or it IS the connecting posture).
        source: ``motion@frame (candidate r)`` of the library frame, for messages and reports.
    """

    goal: Posture
    key: Posture | None
    source: str


def select_goal(ctx: RiseContext, start: Posture, key: Posture | None = None) -> GoalSelection:
    """The connecting posture a plan goes to, as ``robot-rise rise`` selects it.

    Paper 000 section 4.1: the nearest library posture (eq. 1) to the lying posture; with a key
    posture the plan passes through it, and "if a key posture is not a posture in our motion
    database, motion planning is applied again to connect the key posture to a posture in our
    motion database" (section 5.1): the connecting posture is then the one nearest the KEY
    posture, placed where the key posture is. Among the nearest frames of the
    ``DEFAULT_CANDIDATES`` nearest motions (nearest first), the first whose placement is legal is
    taken (as ``rise`` moves on to its next candidate); if none is, the nearest, so that the
    planner reports why it is invalid.

    Args:
        ctx: library, frame index, K-means tree and checker of the scene.
        start: the lying posture.
        key: optional key posture.
    """
    anchor = key if key is not None else start
    tried: list[tuple[Posture, str]] = []
    for rank, conn in enumerate(connection_candidates(ctx.library, ctx.robot, anchor, DEFAULT_CANDIDATES, index=ctx.index, tree=ctx.tree)):
        goal = connecting_posture(ctx.library, ctx.robot, conn, anchor, ctx.checker)
        tried.append((goal, f"{conn.motion}@{conn.frame} (candidate {rank})"))
        if ctx.checker.is_valid(goal):
            break
    else:  # no legal placement: the nearest, so that the planner reports why it is invalid
        goal, _ = tried[0]
    source = next(s for g, s in tried if g is goal)
    if key is not None:
        space = PostureSpace.for_robot(ctx.robot)
        if float(space.distance(space.state(key), space.state(goal))) < KEY_IN_LIBRARY_DISTANCE:
            return GoalSelection(key, None, source)  # the key posture is in the library: plan to it
    return GoalSelection(goal, key, source)


def connection_room(context: RiseContext, connection: Connection, goal: Posture) -> MotionRoom:
    """placement.motion_room for a candidate (always ok in a scene without obstacles)."""
    checker = context.obstacle_checker()
    motion = context.library.get(connection.motion)
    tr = motion.trajectory
    if checker is None or tr.root is None:
        return MotionRoom(True, connection.motion)
    cols = [tr.joint_names.index(j) for j in context.robot.joint_names]
    return motion_room(connection.motion, tr.root, tr.t, tr.q[:, cols], connection.frame, goal, checker)


def _sealing(fn: Callable[..., RiseResult]) -> Callable[..., RiseResult]:
    """``rise``'s result with its trajectory sealed (robot_rise.seal): what was proven is bound to
    its proof wherever rise returns, a retry's or a composed pass's included."""

    @functools.wraps(fn)
    def sealing_rise(*args: Any, **kwargs: Any) -> RiseResult:
        result = fn(*args, **kwargs)
        if result.trajectory is None:
            return result
        return dataclasses.replace(result, trajectory=sealed(result.trajectory))

    return sealing_rise


@_sealing
def rise(
    robot: Robot,
    start: Posture,
    *,
    scene: str | os.PathLike[str] | None = "flat",
    key: Posture | None = None,
    seed: int = 0,
    budget_s: float = 30.0,
    library: MotionLibrary | None = None,
    candidates: int = DEFAULT_CANDIDATES,
    filter_config: FilterConfig = FilterConfig(),
    progress: Callable[[str], None] | None = None,
    context: RiseContext | None = None,
    retries: int = DEFAULT_RETRIES,
    robustness: tuple[ModelVariant, ...] = (),
    candidate_rank: str = DEFAULT_CANDIDATE_RANK,
    composed: bool = False,
) -> RiseResult:
    """Select, plan, filter and prove a get-up from ``start``.

    Args:
        robot: the robot.
        start: the lying posture (validated against the robot; must be collision-free).
        scene: the scene the robot lies in.
        key: optional key posture to pass through (paper 000 section 4.2.3, key postures).
        seed: planner seed (deterministic for a seed).
        budget_s: planning budget per candidate [s].
        library: motion library (default: the robot's shipped library).
        candidates: how many library motions to try, nearest first.
        filter_config: dynamics filter tuning.
        progress: called with a short stage description.
        context: prebuilt checker/library/index for this robot and scene (reuse across rises).
        robustness: extra model variants every proven candidate is replayed under (default none:
            the filter's ensemble proof already replays every variant); the first candidate
            that still stands under all of them is returned, else the first proven one (its
            report's ``robustness`` says which check it failed).
        retries: when every candidate fails (the more-iterations pass included) but the robot
            ends lying at rest, rise again from there this many times (the combined motion is
            proven from the original start; a failed attempt over the torque bound is cut short
            before it).
        candidate_rank: ``"duration"`` tries first the motion with the shortest expected get-up
            (approach + rest of the motion), ``"distance"`` the nearest (paper 000);
            :func:`robot_rise.library.connection_candidates`.
        composed: prove the ensemble by composition where it applies
            (:mod:`robot_rise.filter.composed`: the approach arrives at rest at the library
            motion's start, the variants replay only that, the motion's own proof does the rest):
            the live get-up's first command sooner, for ``ARRIVAL_SETTLE_S`` more robot time.
            Every candidate is tried composed first (cheap: the nominal replay and the variants'
            arrivals; its approach smoothed once, ``QUICK_SMOOTHING``, not three curves compared
            by their jerk); when none is proven so, the candidates are proven whole, as without it.

    Raises:
        PostureError: the start (or key) posture does not fit the robot or is not valid in the scene.
    """
    say = progress or (lambda s: None)
    if composed and filter_config.ensemble:
        if context is None or context.robot is not robot or context.scene != scene or (library is not None and context.library is not library):
            context = RiseContext.build(robot, scene, library)  # one for both passes
        first = _rise_candidates(robot, start, scene, key, seed, budget_s, candidates, filter_config, progress, context, library,
                                 robustness, candidate_rank, composed=True)
        if first.proven:
            return first
        say("no candidate proven composed: proving them whole")
        whole = rise(robot, start, scene=scene, key=key, seed=seed, budget_s=budget_s, library=library, candidates=candidates,
                     filter_config=filter_config, progress=progress, context=context, retries=retries, robustness=robustness,
                     candidate_rank=candidate_rank)
        return dataclasses.replace(whole, attempts=first.attempts + whole.attempts)
    return _rise_candidates(robot, start, scene, key, seed, budget_s, candidates, filter_config, progress, context, library,
                            robustness, candidate_rank, composed=False, retries=retries)


def _rise_candidates(
    robot: Robot,
    start: Posture,
    scene: str | os.PathLike[str] | None,
    key: Posture | None,
    seed: int,
    budget_s: float,
    candidates: int,
    filter_config: FilterConfig,
    progress: Callable[[str], None] | None,
    context: RiseContext | None,
    library: MotionLibrary | None,
    robustness: tuple[ModelVariant, ...],
    candidate_rank: str,
    *,
    composed: bool,
    retries: int = 0,
) -> RiseResult:
    """:func:`rise`'s candidates, each proven composed (``composed``) or whole."""
    say = progress or (lambda s: None)
    if filter_config.max_stretch is None:
        filter_config = dataclasses.replace(filter_config, max_stretch=MAX_STRETCH)
    start = admit_posture(start, robot, where="start posture")
    if context is None or context.robot is not robot or context.scene != scene or (library is not None and context.library is not library):
        context = RiseContext.build(robot, scene, library)
    checker = context.checker
    report = checker.check(start)
    if not report.valid:
        raise PostureError(
            f"start posture is not valid in scene {scene}: {'; '.join(report.reasons()[:3])}",
            hint="settle it first (robot-rise sample settles postures) or check it with robot-rise check-posture",
        )
    if key is not None:
        key = admit_posture(key, robot, where="key posture")
        if not checker.is_valid(key):
            raise PostureError(f"key posture is not valid in scene {scene}: {'; '.join(checker.check(key).reasons()[:3])}")
    library = context.library
    attempts: list[RiseAttempt] = []
    best_unproven: FilterResult | None = None
    best_proven: RiseResult | None = None
    short_of_torque: list[tuple[float, Connection, Trajectory, FilterConfig, int]] = []  # (peak, candidate, commanded, config, join row)
    for conn in connection_candidates(library, robot, key or start, candidates, index=context.index, tree=context.tree, rank=candidate_rank):
        if composed and conn.frame != 0:  # a composed proof starts where the motion's own proof started
            conn = dataclasses.replace(conn, frame=0, time_s=0.0)
        if composed and not _composable(context, library.get(conn.motion), filter_config):  # nothing to plan for: the whole pass may try it
            attempts.append(RiseAttempt(conn.motion, conn.frame, conn.distance, False, skipped=NOT_COMPOSABLE))
            continue
        t0 = time.monotonic()
        say(f"planning to {conn.motion} frame {conn.frame} (distance {conn.distance:.2f})")
        try:
            goal = connecting_posture(library, robot, conn, key or start, checker)
            room = connection_room(context, conn, goal)
            if not room.ok:
                attempts.append(RiseAttempt(conn.motion, conn.frame, conn.distance, False, blocked=room.describe(), seconds={"plan": time.monotonic() - t0}))
                log.info("candidate %s@%d: %s", conn.motion, conn.frame, room.describe())
                continue
            problem = PlanningProblem(start=start, goal=goal, checker=checker, key=key, budget_s=budget_s, seed=seed)
            # composed: the live get-up's latency (one curve, no clearance report)
            planned = plan_trajectory(problem, smoothing=QUICK_SMOOTHING if composed else SmoothingConfig(), report_clearance=not composed)
        except RobotRiseError as e:  # one bad candidate must not end the rise
            attempts.append(RiseAttempt(conn.motion, conn.frame, conn.distance, False, f"error: {e}"))
            log.warning("candidate %s@%d failed: %s", conn.motion, conn.frame, e)
            continue
        t1 = time.monotonic()
        if not planned.solved or planned.trajectory is None:
            reason = planned.result.reason or planned.result.status.value
            attempts.append(RiseAttempt(conn.motion, conn.frame, conn.distance, False, reason, seconds={"plan": t1 - t0}))
            log.info("candidate %s@%d: no path: %s", conn.motion, conn.frame, reason)
            continue
        say(f"filtering {conn.motion} in MuJoCo")
        motion = library.get(conn.motion)
        # a momentum motion stands only near its own timing: slowing it further is wasted replays
        # and one the ensemble's one-at-a-time differences miss is proven on combined ones too
        motion_config = dataclasses.replace(_joining(filter_config, motion), motion_max_stretch=motion.max_stretch)
        if composed:
            quick, why = _composed_candidate(robot, planned.trajectory, motion, conn, start, scene, motion_config, context)
            t2 = time.monotonic()
            attempts.append(RiseAttempt(conn.motion, conn.frame, conn.distance, True, proven=quick is not None,
                                        filter_reason="" if quick is not None else f"composed: {why}",
                                        seconds={"plan": t1 - t0, "filter": t2 - t1, "robustness": 0.0}))
            if quick is not None:
                tr = quick.trajectory.with_report(attempts=[a.describe() for a in attempts], seconds=attempts[-1].seconds, robustness={})
                return RiseResult(True, tr, tuple(attempts), "", quick)
            continue
        result, commanded, join_row = _join_and_filter(robot, planned.trajectory, motion, conn, start, scene, filter_config, motion_config,
                                                       context)
        cautious = ""
        if not result.proven and planned.smoothed is not None and _approach_off_plan(result, planned.trajectory, len(commanded.t), join_row):
            # the servos' fastest approach threw the body where the plan did not go: the same path, cautiously timed
            say(f"filtering {conn.motion} with the cautious approach timing")
            cautious_plan = timed_to_trajectory(time_parameterize(planned.smoothed, robot, limits=TimingLimits.cautious(robot)), start, robot.name,
                                                planned.trajectory.report)
            slow = join_with_blend(cautious_plan, motion.trajectory, conn.frame, blend_s=filter_config.blend_s).with_report(
                **_join_report(cautious_plan, conn), approach_timing="cautious", blend_s=filter_config.blend_s)
            again = dynamics_filter(robot, slow, scene=scene, config=motion_config, start=start,
                                    ensemble=context.ensemble() if filter_config.ensemble else None, join_row=len(cautious_plan.t))
            cautious = "proven" if again.proven else again.reason or "not proven"
            if again.proven:
                result = again
        t2 = time.monotonic()
        robust: dict[str, bool] = {}
        if result.proven:
            say("checking robustness to model errors")
            robust = _robustness(robot, result.trajectory, robustness, scene=scene, filter_config=filter_config, start=start)
        t3 = time.monotonic()
        attempt = RiseAttempt(
            conn.motion, conn.frame, conn.distance, True, proven=result.proven, filter_reason=result.reason,
            seconds={"plan": t1 - t0, "filter": t2 - t1, "robustness": t3 - t2}, robust=all(robust.values()), cautious=cautious,
        )
        attempts.append(attempt)
        extra: dict[str, Any] = {
            "attempts": [a.describe() for a in attempts],
            "seconds": attempt.seconds,
            "robustness": robust,
        }
        if result.proven:
            tr = result.trajectory.with_report(**extra)
            if all(robust.values()):
                return RiseResult(True, tr, tuple(attempts), "", result)
            if best_proven is None:  # proven, but a fluke of the exact model: look for a robust one
                best_proven = RiseResult(True, tr, tuple(attempts), "", result)
            continue
        if best_unproven is None:
            best_unproven = result
        if _short_of_torque(result, motion_config):
            short_of_torque.append((result.proof.peak_torque_ratio, conn, commanded, motion_config, join_row))
    if best_proven is None and short_of_torque:
        # every candidate failed; the one nearest the torque bound, still coming down, gets more iterations
        peak, conn, commanded, motion_config, join_row = min(short_of_torque, key=lambda c: c[0])
        say(f"filtering {conn.motion} with {MORE_ITERATIONS} more iterations (peak torque {peak:.2f} and coming down)")
        t0 = time.monotonic()
        # from its commanded targets again: the filter is deterministic, so its first iterations
        # repeat (a few nominal replays), and the library part's stretch cap keeps its baseline
        longer = dataclasses.replace(motion_config, max_iterations=motion_config.max_iterations + MORE_ITERATIONS)
        result = dynamics_filter(robot, commanded, scene=scene, config=longer, start=start,
                                 ensemble=context.ensemble() if filter_config.ensemble else None, join_row=join_row)
        t1 = time.monotonic()
        robust = _robustness(robot, result.trajectory, robustness, scene=scene, filter_config=filter_config, start=start) if result.proven else {}
        attempts.append(RiseAttempt(conn.motion, conn.frame, conn.distance, True, proven=result.proven, filter_reason=result.reason,
                                    seconds={"plan": 0.0, "filter": t1 - t0, "robustness": time.monotonic() - t1}, robust=all(robust.values()),
                                    more_iterations=MORE_ITERATIONS))  # its plan is the candidate's, counted there
        if result.proven:
            tr = result.trajectory.with_report(attempts=[a.describe() for a in attempts], seconds=attempts[-1].seconds, robustness=robust)
            best_proven = RiseResult(True, tr, tuple(attempts), "", result)
    if best_proven is not None:
        return RiseResult(True, best_proven.trajectory.with_report(attempts=[a.describe() for a in attempts]), tuple(attempts), "", best_proven.filter_result)
    reason = "; ".join(a.describe() for a in attempts) or "no library motion to connect to"
    if retries > 0 and best_unproven is not None:
        recovered = _rise_again_from_where_it_fell(
            robot, best_unproven, scene=scene, seed=seed, budget_s=budget_s, candidates=candidates,
            filter_config=filter_config, progress=progress, context=context, retries=retries - 1, candidate_rank=candidate_rank,
        )
        if recovered is not None:
            return RiseResult(True, recovered.trajectory, tuple(attempts) + recovered.attempts, "", recovered.filter_result)
    tr = best_unproven.trajectory.with_report(attempts=[a.describe() for a in attempts]) if best_unproven else None
    return RiseResult(False, tr, tuple(attempts), reason, best_unproven)


def _join_and_filter(robot: Robot, plan: Trajectory, motion: Motion, conn: Connection, start: Posture, scene: str | os.PathLike[str] | None,
                     filter_config: FilterConfig, motion_config: FilterConfig, context: RiseContext) -> tuple[FilterResult, Trajectory, int]:
    """The candidate's approach joined to its motion and filtered: overlapped first (no stop at
    the join), then with the short step, then with the settling pause; the first proven, except
    that an overlap slowed past the short step's best (the plan, the step, the rest of the motion)
    has the step tried too (its nominal filter first) and the quicker kept. Returns the filter's
    result (its report's ``joins`` says what each join tried gave), the commanded trajectory it
    filtered and its join row (the last tried when none is proven)."""
    rest = float(motion.trajectory.t[-1] - motion.trajectory.t[conn.frame])
    joins: list[tuple[str, float]] = []
    if filter_config.join_overlap_s is not None:
        joins.append(("overlap", filter_config.join_overlap_s))
    # the short step (0.2 s sooner than the pause); the settling pause where the body needs it (a slope)
    joins += [("step", b) for b in dict.fromkeys(b for b in (filter_config.quick_blend_s, filter_config.blend_s) if b is not None)]
    best: tuple[FilterResult, Trajectory, int] | None = None
    tried: tuple[FilterResult, Trajectory, int] | None = None
    seen: list[dict[str, Any]] = []  # each join tried: the report's ``joins``
    for how, seconds in joins:
        if best is not None and (seconds == filter_config.blend_s or best[0].trajectory.duration_s <= plan.duration_s + seconds + rest):
            break  # never the settling pause once a join is proven; the step only where it could be the quicker
        if how == "overlap":
            seconds = overlap_of(plan, motion.trajectory, conn.frame, seconds)
            if seconds <= 0.0:
                continue  # nothing to overlap: a plan of one row, the motion's last frame
            commanded, join_row = join_with_overlap(plan, motion.trajectory, conn.frame, overlap_s=seconds)
            # the plan's rows are those before the motion's first (the lean and the timeline read them)
            commanded = commanded.with_report(**{**_join_report(plan, conn), "plan_rows": join_row}, join_overlap_s=seconds)
        else:
            commanded, join_row = join_with_blend(plan, motion.trajectory, conn.frame, blend_s=seconds), len(plan.t)
            commanded = commanded.with_report(**_join_report(plan, conn), blend_s=seconds)
        if best is not None and filter_config.ensemble:
            # the nominal filter first (a third of the cost): the ensemble and the noise only slow
            # a motion further, so a join the nominal model already makes no quicker cannot win
            nominal = dynamics_filter(robot, commanded, scene=scene, config=dataclasses.replace(motion_config, ensemble=False, noise_replays=0),
                                      start=start, join_row=join_row)
            seen.append({"join": how, "s": seconds, "nominal_only": True, "proven": nominal.proven, "duration_s": nominal.trajectory.duration_s})
            if not nominal.proven or nominal.trajectory.duration_s >= best[0].trajectory.duration_s:
                break
        result = dynamics_filter(robot, commanded, scene=scene, config=motion_config, start=start,
                                 ensemble=context.ensemble() if filter_config.ensemble else None, join_row=join_row)
        seen.append({"join": how, "s": seconds, "nominal_only": False, "proven": result.proven, "duration_s": result.trajectory.duration_s})
        tried = (result, commanded, join_row)
        if result.proven and (best is None or result.trajectory.duration_s < best[0].trajectory.duration_s):
            best = tried
    result, commanded, join_row = best or tried  # type: ignore[misc]
    return dataclasses.replace(result, trajectory=result.trajectory.with_report(joins=seen)), commanded, join_row


def _robustness(robot: Robot, trajectory: Trajectory, variants: tuple[ModelVariant, ...], *, scene: str | os.PathLike[str] | None,
                filter_config: FilterConfig, start: Posture) -> dict[str, bool]:
    """Per robustness variant (by label): does ``trajectory`` still stand under it."""
    return {v.label: stands_under(robot, trajectory, v, scene=scene, config=filter_config, start=start) for v in variants}


def _short_of_torque(result: FilterResult, config: FilterConfig) -> bool:
    """The filter ran out of iterations (not of stretch or duration) on a motion that stood on the
    nominal model, without self collision, only over the torque bound, and whose peak was still
    coming down in its last iteration (one the slowing had not finished with, not one stuck where a
    load no slowing relieves holds it; with one iteration there is no trend: it counts)."""
    proof, history = result.proof, result.iterations
    coming_down = len(history) < 2 or history[-1].peak_envelope_ratio < history[-2].peak_envelope_ratio - MORE_ITERATIONS_MIN_DROP
    return (not result.proven and len(history) >= config.max_iterations and proof.standing and not proof.self_collision
            and proof.peak_torque_ratio > proof.envelope_limit and len(proof.problems) == 1 and coming_down)


def _joining(config: FilterConfig, motion: Motion) -> FilterConfig:
    """``config`` for a proof that joins ``motion``: the combined variants it asks for, and its
    noisy replays where it asks for more than ``config`` (none where ``config`` has none)."""
    noise = max(config.noise_replays, motion.noise_replays) if config.noise_replays > 0 else 0
    return dataclasses.replace(config, combined_variants=motion.combined_variants, noise_replays=noise)


def _join_report(plan: Trajectory, conn: Connection) -> dict[str, Any]:
    """The report entries of a planned approach joined to a library motion."""
    return {**plan.report, "motion": conn.motion, "connecting_frame": conn.frame, "connecting_distance": conn.distance,
            "plan_duration_s": plan.duration_s, "plan_rows": len(plan.t)}


def _composed_candidate(
    robot: Robot,
    plan: Trajectory,
    motion: Motion,
    conn: Connection,
    start: Posture,
    scene: str | os.PathLike[str] | None,
    config: FilterConfig,
    context: RiseContext,
) -> tuple[FilterResult | None, str]:
    """The approach, ``ARRIVAL_SETTLE_S`` on the motion's first targets, the motion unchanged:
    filtered on the nominal model (the motion part never slowed), its ensemble proof composed
    (:func:`robot_rise.filter.composed.prove_composed`). (None, why) where that is not proven."""
    cols = [motion.trajectory.joint_names.index(j) for j in plan.joint_names]
    first = motion.trajectory.q[0, cols]
    step = float(np.max(np.abs(plan.q[-1] - first)))
    if step <= SAME_TARGETS_RAD:  # the plan ends there (but for rounding): end it exactly there, no step
        plan = dataclasses.replace(plan, q=np.vstack([plan.q[:-1], first]))
    else:  # the plan ends within the limits the library's first row may graze: go there first
        gap = max(config.blend_s, step / 2.0)
        root = None if plan.root is None else np.vstack([plan.root, plan.root[-1:]])
        plan = dataclasses.replace(plan, t=np.append(plan.t, plan.t[-1] + gap), q=np.vstack([plan.q, first]), root=root)
    commanded = join_with_blend(plan, motion.trajectory, 0, blend_s=ARRIVAL_SETTLE_S).with_report(**_join_report(plan, conn))
    join_row = len(plan.t)
    t0 = time.perf_counter()
    # the noise check is the start proof's (``StartProof.spread_proven``): noise before the settle is forgotten at rest;
    # untrimmed (``FilterConfig.trim_levels``): the composed proof has no untrimmed approach to fall back on, and the
    # guard waits for this one
    nominal = dynamics_filter(robot, commanded, scene=scene, config=dataclasses.replace(config, ensemble=False, motion_max_stretch=TAIL_MAX_STRETCH,
                                                                                        noise_replays=0, trim_levels=0),
                              start=start, join_row=join_row, stop_at_join=True)
    if not nominal.proven:
        return None, f"the nominal filter, the library part unchanged: {nominal.reason}"
    t1 = time.perf_counter()
    start_proof = context.start_proof(motion, config)
    if start_proof is None or not start_proof.composable:
        return None, NOT_COMPOSABLE
    found = prove_composed(nominal.proof, nominal.recording, nominal.trajectory, join_row=join_row, motion_trajectory=motion.trajectory,
                           start_proof=start_proof, start=start, replayer=context.ensemble(), config=config)
    if found is None:
        return None, "does not apply (another scene, or the library part reshaped)"
    if not found.proof.proven:
        return None, "; ".join(found.proof.problems[:3])
    report = {**found.report, "ensemble_seconds": time.perf_counter() - t1, "ensemble_rounds": 0, "nominal_filter_seconds": t1 - t0,
              NOISE_CHECK_KEY: {"from_start_proof": motion.name}}
    return dataclasses.replace(nominal, trajectory=nominal.trajectory.with_report(**report), proof=found.proof,
                               report={**nominal.report, **report}), ""


def _composable(context: RiseContext, motion: Motion, config: FilterConfig) -> bool:
    """The motion's start proof allows a composed proof (``StartProof.composable``)."""
    start_proof = context.start_proof(motion, config)
    return start_proof is not None and start_proof.composable


def _approach_off_plan(result: FilterResult, plan: Trajectory, commanded_rows: int, join_row: int) -> bool:
    """The simulated body ended the planned approach lying otherwise than planned: its gravity
    direction (in the root frame) more than APPROACH_OFF_PLAN_RAD from the planned root's.

    The planned root comes from ``plan`` (the filter's output carries no root): the filter only
    retimes the ``commanded_rows`` it was given, so row ``join_row - 1`` (the plan's rows come
    first) still ends the approach; where the rows differ, nothing is said."""
    tr, rec = result.trajectory, result.recording
    end = min(join_row, len(plan.t)) - 1
    if plan.root is None or len(tr.t) != commanded_rows or not 0 <= end < len(tr.t) or len(rec.t) == 0:
        return False
    k = min(int(np.searchsorted(rec.t, tr.t[end])), len(rec.t) - 1)
    return bool(gravity_angle_rad(rec.root_pose[k, 3:], plan.root[end, 3:]) > APPROACH_OFF_PLAN_RAD)


def _rise_again_from_where_it_fell(
    robot: Robot,
    failed: FilterResult,
    *,
    scene: str | os.PathLike[str] | None,
    seed: int,
    budget_s: float,
    candidates: int,
    filter_config: FilterConfig,
    progress: Callable[[str], None] | None,
    context: RiseContext,
    retries: int,
    candidate_rank: str = DEFAULT_CANDIDATE_RANK,
) -> RiseResult | None:
    """A failed get-up that ends lying at rest is followed by a new rise from where it lies.

    As a robot would after a failed attempt: the final simulated state (after the judge's hold)
    becomes a new lying posture; the combined targets (failed attempt, its hold, the new rise)
    are proven by replaying them from the original start. An attempt that goes over the torque
    bound is cut short before it first (its replay from there on stands in for the failed one's):
    the whole of it would go over the bound in the combined replay too.
    """
    first, rec = failed.trajectory, failed.recording
    stopped = _stopped_before_the_torque_bound(robot, failed, scene=scene, filter_config=filter_config)
    if stopped is not None:  # the attempt as far as it keeps within the torque bound: a combined proof can hold
        first, rec = stopped
    if classify_lying(rec.root_pose[-1, 3:]) == "upright":
        return None
    if np.max(np.abs(rec.qd[-1])) > RECOVERY_MAX_JOINT_SPEED or np.linalg.norm(rec.root_vel[-1]) > RECOVERY_MAX_ROOT_SPEED:
        return None
    joints = np.clip(rec.q[-1], robot.joint_lower, robot.joint_upper)
    fallen = Posture(robot.name, rec.root_pose[-1, :3], rec.root_pose[-1, 3:], dict(zip(robot.joint_names, joints)))
    if not context.checker.is_valid(fallen):
        return None
    log.info("first attempt %s lying (%s); rising again from there", f"stopped at {first.duration_s:.2f} s, before the torque bound," if stopped else "ended",
             classify_lying(fallen.root_quat_wxyz))
    tried: list[RiseAttempt] = []
    # the quickest get-up from where it fell first; where that is proven alone but not whole (from
    # the original start, after the fall), the nearest motions', the safest joins (where nothing
    # was proven alone, they were among the candidates already)
    for rank in dict.fromkeys((candidate_rank, "distance")):
        again = rise(
            robot, fallen, scene=scene, seed=seed + 1, budget_s=budget_s, candidates=candidates, filter_config=filter_config,
            progress=progress, context=context, retries=retries, candidate_rank=rank,
        )
        tried.extend(again.attempts)
        if not again.proven or again.trajectory is None:
            return None
        combined = _after_the_fall(robot, first, failed.reason, again, scene=scene, filter_config=filter_config, context=context,
                                   stopped=stopped is not None)
        if combined is not None:
            return RiseResult(True, combined, tuple(tried), "", again.filter_result)
    return None


def _stopped_before_the_torque_bound(
    robot: Robot, failed: FilterResult, *, scene: str | os.PathLike[str] | None, filter_config: FilterConfig
) -> tuple[Trajectory, Recording] | None:
    """A failed attempt that goes over the torque bound, stopped before it does
    (:func:`robot_rise.filter.stopped_before_torque_bound`), and its replay with the judge's hold
    (None: it never goes over the bound). Wolfgang-OP, a side start whose arm the approach pressed
    under the body stalled the servo at the envelope, then lay prone and was proven from there,
    but not after that whole attempt."""
    limit = failed.proof.envelope_limit  # the bound the attempt failed (the filter's proving one)
    stopped = stopped_before_torque_bound(failed.trajectory, failed.recording, limit, command_limits_for(robot))
    if stopped is None:
        return None
    rec = Player(robot, scene).play(stopped, hold_s=filter_config.hold_s)
    # a stop that goes over the bound itself (the ramp to where the joints are) cannot start a combined proof either
    return (stopped, rec) if rec.peak_envelope_ratio <= limit else None


def _after_the_fall(
    robot: Robot,
    first: Trajectory,
    first_reason: str,
    again: RiseResult,
    *,
    scene: str | os.PathLike[str] | None,
    filter_config: FilterConfig,
    context: RiseContext,
    stopped: bool = False,
) -> Trajectory | None:
    """The failed attempt ``first`` (``stopped``: cut short before the torque bound), its hold and
    the new rise as one trajectory, proven from the original start (None where it is not)."""
    held_until = first.duration_s + filter_config.hold_s
    stage1 = Trajectory(first.robot, first.joint_names, np.append(first.t, held_until), np.vstack([first.q, first.q[-1:]]), first.start, {})
    limits = command_limits_for(robot)
    combined = conform(join_with_blend(stage1, again.trajectory, 0, blend_s=filter_config.blend_s), limits)
    player = Player(robot, scene)
    proving = filter_config.proving()  # as the filter proves: headroom under check's bound
    rec, verdict, proof = prove(robot, combined, scene=scene, config=proving, player=player, start=first.start)
    noise: dict[str, Any] = {}
    if proof.proven and filter_config.noise_replays > 0:  # the fall is where a landing is most sensitive
        checked = noise_check(combined, rec, player, start=first.start, config=proving)[0]
        proof, noise = with_noise(proof, checked), {NOISE_CHECK_KEY: checked.to_dict()}
    recs: list = []
    if proof.proven and filter_config.ensemble:
        replayed, recs = context.ensemble().replay(combined, start=first.start, config=filter_config)
        proof = with_ensemble(proof, replayed)
    if not proof.proven:
        log.info("combined recovery not proven on replay: %s", list(proof.problems))
        return None
    # the combined motion's proof, limits and predicted positions replace the second rise's
    entries = {**proof.to_dict(), **noise, COMMAND_LIMITS_KEY: limits.to_dict(), PREDICTED_KEY: predicted_positions(rec, ensemble=recs)}
    return combined.with_report(
        **{k: v for k, v in again.trajectory.report.items() if k not in entries and k != NOISE_CHECK_KEY},
        **entries,
        recovery={"first_attempt_until_s": held_until, "first_attempt": first_reason, "then": again.trajectory.report.get("motion"),
                  **({"first_attempt_stopped_at_s": first.duration_s} if stopped else {})},
    )


