"""One candidate of a rise: its approach joined to its library motion, filtered and proven (whole or composed)."""

from __future__ import annotations

import dataclasses
import os
import time
from typing import Any

import numpy as np

from robot_rise.constants import APPROACH_OFF_PLAN_RAD
from robot_rise.filter import FilterConfig, FilterResult, dynamics_filter, join_with_blend, join_with_overlap, overlap_of
from robot_rise.library import Connection, Motion
from robot_rise.model import Robot
from robot_rise.posture import Posture
from robot_rise.proof import ARRIVAL_SETTLE_S, NOISE_CHECK_KEY, TAIL_MAX_STRETCH, gravity_angle_rad, prove_composed, stands_under
from robot_rise.rise.context import RiseContext, joining
from robot_rise.sim.variants import ModelVariant
from robot_rise.trajectory import Trajectory

__all__ = [
    "NOT_COMPOSABLE",
    "MORE_ITERATIONS",
    "join_and_filter",
    "robustness_of",
    "short_of_torque",
    "motion_config_for",
    "nominal_only",
    "join_report",
    "composed_candidate",
    "composable",
    "approach_off_plan",
]

NOT_COMPOSABLE = "not joined by a composed proof: its start proof does not stand on every variant, or its nominal torque is not proven from every arrival-spread start"
# a candidate that stood and was only over the torque bound, still coming down when the filter's
# iterations ran out (by at least this much in its last one), is filtered again with this many more
# once no candidate is proven (Wolfgang-OP, a side start: an elbow under the 6.1 kg body came
# down 1.00 -> 0.99 -> 0.96 in iterations 4-6 as its approach was slowed; the bound is 0.88)
MORE_ITERATIONS = 6
MORE_ITERATIONS_MIN_DROP = 0.005
SAME_TARGETS_RAD = 1e-4  # [rad] a composed approach ending this close to the motion's first targets ends on them (rounding, far below one servo tick of 1.5 mrad): no 0.3 s step there


def join_and_filter(robot: Robot, plan: Trajectory, motion: Motion, conn: Connection, start: Posture, scene: str | os.PathLike[str] | None,
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
            commanded = commanded.with_report(**{**join_report(plan, conn), "plan_rows": join_row}, join_overlap_s=seconds)
        else:
            commanded, join_row = join_with_blend(plan, motion.trajectory, conn.frame, blend_s=seconds), len(plan.t)
            commanded = commanded.with_report(**join_report(plan, conn), blend_s=seconds)
        if best is not None and filter_config.proof.ensemble:
            # the nominal filter first (a third of the cost): the ensemble and the noise only slow
            # a motion further, so a join the nominal model already makes no quicker cannot win
            nominal = dynamics_filter(robot, commanded, scene=scene, config=nominal_only(motion_config),
                                      start=start, join_row=join_row)
            seen.append({"join": how, "s": seconds, "nominal_only": True, "proven": nominal.proven, "duration_s": nominal.trajectory.duration_s})
            if not nominal.proven or nominal.trajectory.duration_s >= best[0].trajectory.duration_s:
                break
        result = dynamics_filter(robot, commanded, scene=scene, config=motion_config, start=start,
                                 ensemble=context.ensemble() if filter_config.proof.ensemble else None, join_row=join_row)
        seen.append({"join": how, "s": seconds, "nominal_only": False, "proven": result.proven, "duration_s": result.trajectory.duration_s})
        tried = (result, commanded, join_row)
        if result.proven and (best is None or result.trajectory.duration_s < best[0].trajectory.duration_s):
            best = tried
    result, commanded, join_row = best or tried  # type: ignore[misc]
    return dataclasses.replace(result, trajectory=result.trajectory.with_report(joins=seen)), commanded, join_row


def robustness_of(robot: Robot, trajectory: Trajectory, variants: tuple[ModelVariant, ...], *, scene: str | os.PathLike[str] | None,
                filter_config: FilterConfig, start: Posture) -> dict[str, bool]:
    """Per robustness variant (by label): does ``trajectory`` still stand under it."""
    return {v.label: stands_under(robot, trajectory, v, scene=scene, config=filter_config.proof, start=start) for v in variants}


def short_of_torque(result: FilterResult, config: FilterConfig) -> bool:
    """The filter ran out of iterations (not of stretch or duration) on a motion that stood on the
    nominal model, without self collision, only over the torque bound, and whose peak was still
    coming down in its last iteration (one the slowing had not finished with, not one stuck where a
    load no slowing relieves holds it; with one iteration there is no trend: it counts)."""
    proof, history = result.proof, result.iterations
    coming_down = len(history) < 2 or history[-1].peak_envelope_ratio < history[-2].peak_envelope_ratio - MORE_ITERATIONS_MIN_DROP
    return (not result.proven and len(history) >= config.max_iterations and proof.standing and not proof.self_collision
            and proof.peak_torque_ratio > proof.envelope_limit and len(proof.problems) == 1 and coming_down)


def motion_config_for(config: FilterConfig, motion: Motion) -> FilterConfig:
    """``config`` for filtering a get-up that joins ``motion``: its proof joining it
    (``context.joining``), the motion's own timing window on the part from the join on.

    A momentum motion stands only near its own timing: slowing it further is wasted replays,
    and one the ensemble's one-at-a-time differences miss is proven on combined ones too."""
    return dataclasses.replace(config, proof=joining(config.proof, motion), motion_max_stretch=motion.max_stretch)


def nominal_only(config: FilterConfig, **changes: Any) -> FilterConfig:
    """``config`` filtering on the nominal model alone: no ensemble, no noisy replays (and ``changes``)."""
    return dataclasses.replace(config, proof=dataclasses.replace(config.proof, ensemble=False, noise_replays=0), **changes)


def join_report(plan: Trajectory, conn: Connection) -> dict[str, Any]:
    """The report entries of a planned approach joined to a library motion."""
    return {**plan.report, "motion": conn.motion, "connecting_frame": conn.frame, "connecting_distance": conn.distance,
            "plan_duration_s": plan.duration_s, "plan_rows": len(plan.t)}


def composed_candidate(
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
    (:func:`robot_rise.proof.composed.prove_composed`). (None, why) where that is not proven."""
    cols = [motion.trajectory.joint_names.index(j) for j in plan.joint_names]
    first = motion.trajectory.q[0, cols]
    step = float(np.max(np.abs(plan.q[-1] - first)))
    if step <= SAME_TARGETS_RAD:  # the plan ends there (but for rounding): end it exactly there, no step
        plan = dataclasses.replace(plan, q=np.vstack([plan.q[:-1], first]))
    else:  # the plan ends within the limits the library's first row may graze: go there first
        gap = max(config.blend_s, step / 2.0)
        root = None if plan.root is None else np.vstack([plan.root, plan.root[-1:]])
        plan = dataclasses.replace(plan, t=np.append(plan.t, plan.t[-1] + gap), q=np.vstack([plan.q, first]), root=root)
    commanded = join_with_blend(plan, motion.trajectory, 0, blend_s=ARRIVAL_SETTLE_S).with_report(**join_report(plan, conn))
    join_row = len(plan.t)
    t0 = time.perf_counter()
    # the noise check is the start proof's (``StartProof.spread_proven``): noise before the settle is forgotten at rest;
    # untrimmed (``FilterConfig.trim_levels``): the composed proof has no untrimmed approach to fall back on, and the
    # guard waits for this one
    nominal = dynamics_filter(robot, commanded, scene=scene, config=nominal_only(config, motion_max_stretch=TAIL_MAX_STRETCH, trim_levels=0),
                              start=start, join_row=join_row, stop_at_join=True)
    if not nominal.proven:
        return None, f"the nominal filter, the library part unchanged: {nominal.reason}"
    t1 = time.perf_counter()
    start_proof = context.start_proof(motion, config.proof)
    if start_proof is None or not start_proof.composable:
        return None, NOT_COMPOSABLE
    found = prove_composed(nominal.proof, nominal.recording, nominal.trajectory, join_row=join_row, motion_trajectory=motion.trajectory,
                           start_proof=start_proof, start=start, replayer=context.ensemble(), config=config.proof)
    if found is None:
        return None, "does not apply (another scene, or the library part reshaped)"
    if not found.proof.proven:
        return None, "; ".join(found.proof.problems[:3])
    report = {**found.report, "ensemble_seconds": time.perf_counter() - t1, "ensemble_rounds": 0, "nominal_filter_seconds": t1 - t0,
              NOISE_CHECK_KEY: {"from_start_proof": motion.name}}
    return dataclasses.replace(nominal, trajectory=nominal.trajectory.with_report(**report), proof=found.proof,
                               report={**nominal.report, **report}), ""


def composable(context: RiseContext, motion: Motion, config: FilterConfig) -> bool:
    """The motion's start proof allows a composed proof (``StartProof.composable``)."""
    start_proof = context.start_proof(motion, config.proof)
    return start_proof is not None and start_proof.composable


def approach_off_plan(result: FilterResult, plan: Trajectory, commanded_rows: int, join_row: int) -> bool:
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
