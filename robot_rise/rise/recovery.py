"""Recovery: a failed get-up that ends lying at rest is followed by a new rise from where it lies.

As a robot would after a failed attempt: the final simulated state (after the judge's hold)
becomes a new lying posture; the combined targets (failed attempt, its hold, the new rise) are
proven by replaying them from the original start. An attempt that goes over the torque bound is
cut short before it first (its replay from there on stands in for the failed one's): the whole of
it would go over the bound in the combined replay too. A loop, falls deep: each level rises from
where the previous level's best attempt fell.
"""

from __future__ import annotations

import dataclasses
import logging
import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from robot_rise.filter import COMMAND_LIMITS_KEY, FilterConfig, FilterResult, command_limits_for, conform, join_with_blend, stopped_before_torque_bound
from robot_rise.model import Robot
from robot_rise.posture import Posture
from robot_rise.proof import NOISE_CHECK_KEY, PREDICTED_KEY, noise_check, predicted_positions, prove, with_ensemble, with_noise
from robot_rise.rise.context import RiseContext
from robot_rise.rise.options import RiseOptions
from robot_rise.rise.result import RiseAttempt, RiseResult
from robot_rise.sampling import classify_lying
from robot_rise.sim.player import Player, Recording
from robot_rise.trajectory import Trajectory

__all__ = ["Fall", "fall_of", "recover", "stopped_before_the_torque_bound", "after_the_fall"]

log = logging.getLogger(__name__)

RECOVERY_MAX_JOINT_SPEED = 0.5  # [rad/s] the robot must be at rest to count as lying there
RECOVERY_MAX_ROOT_SPEED = 0.2  # [m/s, rad/s combined norm]


@dataclass(frozen=True)
class Fall:
    """Where a failed attempt left the robot: the attempt (cut short before the torque bound
    where it went over, ``stopped``), why it failed, and the lying posture it ended in."""

    first: Trajectory
    reason: str
    stopped: bool
    lying: Posture


def fall_of(robot: Robot, failed: FilterResult, *, scene: str | os.PathLike[str] | None, filter_config: FilterConfig,
            context: RiseContext) -> Fall | None:
    """The lying posture ``failed`` ends in at rest (None: upright, still moving, or not a valid start)."""
    first, rec = failed.trajectory, failed.recording
    stopped = stopped_before_the_torque_bound(robot, failed, scene=scene, filter_config=filter_config)
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
    return Fall(first, failed.reason, stopped is not None, fallen)


def recover(robot: Robot, failed: FilterResult, options: RiseOptions, context: RiseContext,
            rise_from: Callable[[Posture, RiseOptions], RiseResult]) -> RiseResult | None:
    """A proven get-up from the original start through the falls after ``failed`` (None: none).

    ``rise_from(posture, options)`` is one rise without recovery (``robot_rise.rise.pipeline``).
    At each level the quickest get-up from where it fell first; where that is proven alone but not
    whole (from the original start, after the falls), the nearest motions' (where nothing was
    proven alone, they were among the candidates already). Where the first rank proves nothing,
    the next level (up to ``options.retries``) rises from where that one fell.
    """
    falls: list[Fall] = []
    tried: list[RiseAttempt] = []
    for depth in range(options.retries):
        fall = fall_of(robot, failed, scene=options.scene, filter_config=options.filter_config, context=context)
        if fall is None:
            return None
        falls.append(fall)
        deeper: FilterResult | None = None
        for rank in dict.fromkeys((options.candidate_rank, "distance")):
            again = rise_from(fall.lying, dataclasses.replace(options, seed=options.seed + depth + 1, candidate_rank=rank, key=None))
            tried.extend(again.attempts)
            if not again.proven or again.trajectory is None:
                deeper = again.filter_result if rank == options.candidate_rank else None
                break
            combined = _through_the_falls(robot, falls, again, options, context)
            if combined is not None:
                return RiseResult(True, combined, tuple(tried), "", again.filter_result)
        if deeper is None:
            return None
        failed = deeper
    return None


def _through_the_falls(robot: Robot, falls: list[Fall], again: RiseResult, options: RiseOptions, context: RiseContext) -> Trajectory | None:
    """The falls (last first) and the rise after them as one trajectory, proven from the first start."""
    for fall in reversed(falls):
        combined = after_the_fall(robot, fall.first, fall.reason, again, scene=options.scene, filter_config=options.filter_config,
                                  context=context, stopped=fall.stopped)
        if combined is None:
            return None
        again = RiseResult(True, combined, again.attempts, "", again.filter_result)
    return again.trajectory


def stopped_before_the_torque_bound(
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
    rec = Player(robot, scene).play(stopped, hold_s=filter_config.proof.hold_s)
    # a stop that goes over the bound itself (the ramp to where the joints are) cannot start a combined proof either
    return (stopped, rec) if rec.peak_envelope_ratio <= limit else None


def after_the_fall(
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
    held_until = first.duration_s + filter_config.proof.hold_s
    stage1 = Trajectory(first.robot, first.joint_names, np.append(first.t, held_until), np.vstack([first.q, first.q[-1:]]), first.start, {})
    limits = command_limits_for(robot)
    combined = conform(join_with_blend(stage1, again.trajectory, 0, blend_s=filter_config.blend_s), limits)
    player = Player(robot, scene)
    proving = filter_config.proving()  # as the filter proves: headroom under check's bound
    rec, verdict, proof = prove(robot, combined, scene=scene, config=proving.proof, player=player, start=first.start)
    noise: dict[str, Any] = {}
    if proof.proven and filter_config.proof.noise_replays > 0:  # the fall is where a landing is most sensitive
        checked = noise_check(combined, rec, player, start=first.start, config=proving.proof)[0]
        proof, noise = with_noise(proof, checked), {NOISE_CHECK_KEY: checked.to_dict()}
    recs: list = []
    if proof.proven and filter_config.proof.ensemble:
        replayed, recs = context.ensemble().replay(combined, start=first.start, config=filter_config.proof)
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
