"""The product's main job: from a lying posture to a proven get-up trajectory (``rise``).

select (paper 000 section 4.1) -> plan (RRT-blossom, section 4.2) -> smooth and time -> join the
library motion -> dynamics filter (section 4.3) -> proof. When a candidate fails (no path within
the budget, or the filter cannot make it stand), the next library motion is tried; the result
lists every attempt and why it failed. When every candidate fails, the one the filter gave up on
while its torque peak was still coming down is filtered with ``MORE_ITERATIONS`` more; then the
robot rises again from where the failed attempt leaves it lying (``robot_rise.rise.recovery``).
Passes, in order: composed (``RiseOptions.composed``), whole, recovery; no pass calls ``rise``.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Callable
from typing import Any

from robot_rise.errors import PostureError, RobotRiseError
from robot_rise.filter import FilterConfig, FilterResult, dynamics_filter, join_with_blend
from robot_rise.library import Connection, connecting_posture, connection_candidates
from robot_rise.model import Robot
from robot_rise.planning.problem import PlanningProblem
from robot_rise.planning.smoothing import QUICK_SMOOTHING, SmoothingConfig
from robot_rise.planning.timing import TimingLimits, time_parameterize
from robot_rise.planning.to_trajectory import plan_trajectory, timed_to_trajectory
from robot_rise.posture import Posture, admit_posture
from robot_rise.rise.candidate import (MORE_ITERATIONS, NOT_COMPOSABLE, approach_off_plan, composable, composed_candidate, join_and_filter,
                                       join_report, motion_config_for, robustness_of, short_of_torque)
from robot_rise.rise.context import RiseContext, connection_room
from robot_rise.rise.options import RiseOptions
from robot_rise.rise.recovery import recover
from robot_rise.rise.result import RiseAttempt, RiseResult
from robot_rise.seal import sealed
from robot_rise.trajectory import Trajectory

__all__ = ["MAX_STRETCH", "rise"]

log = logging.getLogger(__name__)

MAX_STRETCH = 2.5  # FilterConfig.max_stretch of a rise (unless the caller sets one): a library motion slowed more is the next candidate's turn


def rise(robot: Robot, start: Posture, options: RiseOptions = RiseOptions(), context: RiseContext | None = None,
         progress: Callable[[str], None] | None = None) -> RiseResult:
    """Select, plan, filter and prove a get-up from ``start``; the trajectory sealed (``robot_rise.seal``).

    Args:
        robot: the robot.
        start: the lying posture (validated against the robot; must be collision-free).
        options: scene, key posture, seed, budget, candidates, retries, proof (``RiseOptions``).
        context: prebuilt checker/library/index for this robot and scene (reuse across rises).
        progress: called with a short stage description.

    Raises:
        PostureError: the start (or key) posture does not fit the robot or is not valid in the scene.
    """
    say = progress or (lambda s: None)
    if context is None or context.robot is not robot or context.scene != options.scene or (
            options.library is not None and context.library is not options.library):
        context = RiseContext.build(robot, options.scene, options.library)
    ctx = context

    def rise_from(posture: Posture, opts: RiseOptions, composed: bool = False) -> RiseResult:
        return _candidates_pass(robot, posture, opts, ctx, say, composed=composed)

    earlier: tuple[RiseAttempt, ...] = ()
    if options.composed and options.filter_config.proof.ensemble:
        first = rise_from(start, options, composed=True)
        if first.proven:
            return _sealed(first)
        say("no candidate proven composed: proving them whole")
        earlier = first.attempts
    whole = rise_from(start, options)
    if not whole.proven and options.retries > 0 and whole.filter_result is not None:
        recovered = recover(robot, whole.filter_result, options, ctx, rise_from)
        if recovered is not None:
            whole = RiseResult(True, recovered.trajectory, whole.attempts + recovered.attempts, "", recovered.filter_result)
    return _sealed(dataclasses.replace(whole, attempts=earlier + whole.attempts))


def _sealed(result: RiseResult) -> RiseResult:
    """``result`` with its trajectory sealed: what was proven is bound to its proof."""
    return result if result.trajectory is None else dataclasses.replace(result, trajectory=sealed(result.trajectory))


def _candidates_pass(robot: Robot, start: Posture, options: RiseOptions, context: RiseContext, say: Callable[[str], None], *,
                     composed: bool) -> RiseResult:
    """One pass over the library's candidates, each proven composed (``composed``) or whole; no recovery."""
    scene, key = options.scene, options.key
    filter_config = options.filter_config
    if filter_config.max_stretch is None:
        filter_config = dataclasses.replace(filter_config, max_stretch=MAX_STRETCH)
    start = admit_posture(start, robot, where="start posture")
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
    torque_short: list[tuple[float, Connection, Trajectory, FilterConfig, int]] = []  # (peak, candidate, commanded, config, join row)
    for conn in connection_candidates(library, robot, key or start, options.candidates, index=context.index, tree=context.tree, rank=options.candidate_rank):
        if composed and conn.frame != 0:  # a composed proof starts where the motion's own proof started
            conn = dataclasses.replace(conn, frame=0, time_s=0.0)
        if composed and not composable(context, library.get(conn.motion), filter_config):  # nothing to plan for: the whole pass may try it
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
            problem = PlanningProblem(start=start, goal=goal, checker=checker, key=key, budget_s=options.budget_s, seed=options.seed)
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
        motion_config = motion_config_for(filter_config, motion)
        if composed:
            quick, why = composed_candidate(robot, planned.trajectory, motion, conn, start, scene, motion_config, context)
            t2 = time.monotonic()
            attempts.append(RiseAttempt(conn.motion, conn.frame, conn.distance, True, proven=quick is not None,
                                        filter_reason="" if quick is not None else f"composed: {why}",
                                        seconds={"plan": t1 - t0, "filter": t2 - t1, "robustness": 0.0}))
            if quick is not None:
                tr = quick.trajectory.with_report(attempts=[a.describe() for a in attempts], seconds=attempts[-1].seconds, robustness={})
                return RiseResult(True, tr, tuple(attempts), "", quick)
            continue
        result, commanded, join_row = join_and_filter(robot, planned.trajectory, motion, conn, start, scene, filter_config, motion_config,
                                                       context)
        cautious = ""
        if not result.proven and planned.smoothed is not None and approach_off_plan(result, planned.trajectory, len(commanded.t), join_row):
            # the servos' fastest approach threw the body where the plan did not go: the same path, cautiously timed
            say(f"filtering {conn.motion} with the cautious approach timing")
            cautious_plan = timed_to_trajectory(time_parameterize(planned.smoothed, robot, limits=TimingLimits.cautious(robot)), start, robot.name,
                                                planned.trajectory.report)
            slow = join_with_blend(cautious_plan, motion.trajectory, conn.frame, blend_s=filter_config.blend_s).with_report(
                **join_report(cautious_plan, conn), approach_timing="cautious", blend_s=filter_config.blend_s)
            again = dynamics_filter(robot, slow, scene=scene, config=motion_config, start=start,
                                    ensemble=context.ensemble() if filter_config.proof.ensemble else None, join_row=len(cautious_plan.t))
            cautious = "proven" if again.proven else again.reason or "not proven"
            if again.proven:
                result = again
        t2 = time.monotonic()
        robust: dict[str, bool] = {}
        if result.proven:
            say("checking robustness to model errors")
            robust = robustness_of(robot, result.trajectory, options.robustness, scene=scene, filter_config=filter_config, start=start)
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
        if short_of_torque(result, motion_config):
            torque_short.append((result.proof.peak_torque_ratio, conn, commanded, motion_config, join_row))
    if best_proven is None and torque_short:
        # every candidate failed; the one nearest the torque bound, still coming down, gets more iterations
        peak, conn, commanded, motion_config, join_row = min(torque_short, key=lambda c: c[0])
        say(f"filtering {conn.motion} with {MORE_ITERATIONS} more iterations (peak torque {peak:.2f} and coming down)")
        t0 = time.monotonic()
        # from its commanded targets again: the filter is deterministic, so its first iterations
        # repeat (a few nominal replays), and the library part's stretch cap keeps its baseline
        longer = dataclasses.replace(motion_config, max_iterations=motion_config.max_iterations + MORE_ITERATIONS)
        result = dynamics_filter(robot, commanded, scene=scene, config=longer, start=start,
                                 ensemble=context.ensemble() if filter_config.proof.ensemble else None, join_row=join_row)
        t1 = time.monotonic()
        robust = robustness_of(robot, result.trajectory, options.robustness, scene=scene, filter_config=filter_config, start=start) if result.proven else {}
        attempts.append(RiseAttempt(conn.motion, conn.frame, conn.distance, True, proven=result.proven, filter_reason=result.reason,
                                    seconds={"plan": 0.0, "filter": t1 - t0, "robustness": time.monotonic() - t1}, robust=all(robust.values()),
                                    more_iterations=MORE_ITERATIONS))  # its plan is the candidate's, counted there
        if result.proven:
            tr = result.trajectory.with_report(attempts=[a.describe() for a in attempts], seconds=attempts[-1].seconds, robustness=robust)
            best_proven = RiseResult(True, tr, tuple(attempts), "", result)
    if best_proven is not None:
        return RiseResult(True, best_proven.trajectory.with_report(attempts=[a.describe() for a in attempts]), tuple(attempts), "", best_proven.filter_result)
    reason = "; ".join(a.describe() for a in attempts) or "no library motion to connect to"
    tr = best_unproven.trajectory.with_report(attempts=[a.describe() for a in attempts]) if best_unproven else None
    return RiseResult(False, tr, tuple(attempts), reason, best_unproven)
