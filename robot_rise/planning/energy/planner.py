"""The energy-driven planner behind the shared interface: ``plan_energy(problem) -> PlanResult`` and ``EnergyPlanner``.

Each leg (start -> goal, or through ``problem.key``) is planned by Algorithm 1
(``energy_interpolate``), retried with other fall-off exponents after a local minimum, then
reduced and smoothed in what is left of the budget: key postures, straightened limbs, second
stage, dense output.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from robot_rise.constants import FALLOFF_RETRY_SCHEDULE
from robot_rise.planning.energy.config import EnergyConfig
from robot_rise.planning.energy.constraints import PositionalConstraint
from robot_rise.planning.energy.dense import dense_output
from robot_rise.planning.energy.gli import GliMatrix
from robot_rise.planning.energy.interpolate import InterpolationOutcome, energy_interpolate
from robot_rise.planning.energy.keyframes import safe_zone_keyframes
from robot_rise.planning.energy.projection import second_stage
from robot_rise.planning.energy.repulsive import RepulsiveEnergy
from robot_rise.planning.energy.straighten import straighten_limbs
from robot_rise.planning.motion_validator import MotionValidator
from robot_rise.planning.problem import PlanningProblem, PlanResult, PlanStatus, PostureSequence
from robot_rise.posture import Posture, posture_from_qpos
from robot_rise.validity import ValidityChecker

__all__ = ["plan_energy", "EnergyPlanner"]

log = logging.getLogger(__name__)


def _refine_leg(
    checker: ValidityChecker,
    q_leg: np.ndarray,
    gli: GliMatrix,
    validator: MotionValidator,
    params: EnergyConfig,
    constraints: tuple[PositionalConstraint, ...],
    deadline: float,
    leg_stats: dict[str, Any],
) -> np.ndarray:
    """One leg's legal first-stage motion reduced and smoothed as ``params`` asks, within ``deadline``.

    Key postures, straightening, second stage and dense output in turn, each legal wherever its
    input is; ``leg_stats`` gets their counters and ``stopped_on_budget``, the steps that the
    deadline cut short (an empty list when none). Returns qpos rows, shape (K', nq).
    """
    stopped: list[str] = []
    res = params.verify_resolution_m
    if params.keyframes and len(q_leg) > 2:
        s: dict[str, Any] = {}
        q_leg = safe_zone_keyframes(checker, q_leg, gli, threshold=params.gli_threshold, resolution_m=res,
                                    validator=validator, deadline=deadline, stats=s)
        leg_stats["key_postures"] = len(q_leg)
        if s["stopped_on_budget"]:
            stopped.append("key postures")
    if params.straighten_limbs and len(q_leg) > 2:
        s = {}
        q_leg = straighten_limbs(checker, q_leg, resolution_m=res, root_translation_scale_m=params.root_translation_scale_m,
                                 validator=validator, deadline=deadline, stats=s)
        leg_stats["straightened"] = s["straightened"]
        if s["stopped_on_budget"]:
            stopped.append("straightening")
    if params.second_stage is not None and len(q_leg) > 1:
        s2: dict[str, Any] = {}
        q_leg = second_stage(checker, q_leg, params=params.second_stage, constraints=constraints, resolution_m=res,
                             root_translation_scale_m=params.root_translation_scale_m, validator=validator, deadline=deadline, stats=s2)
        leg_stats["second_stage"] = s2
        if s2["stopped_on_budget"]:
            stopped.append("second stage")
        if params.dense_output:
            s = {}
            q_leg = dense_output(checker, q_leg, resolution_m=res, root_translation_scale_m=params.root_translation_scale_m,
                                 validator=validator, deadline=deadline, stats=s)
            s2.update(output=s["output"], output_frames=s["output_frames"])
            if s["stopped_on_budget"]:
                stopped.append("dense output")
    leg_stats["stopped_on_budget"] = stopped
    return q_leg


def plan_energy(
    problem: PlanningProblem,
    *,
    params: EnergyConfig = EnergyConfig(),
    constraints: tuple[PositionalConstraint, ...] = (),
    retry_falloffs: tuple[int, ...] = FALLOFF_RETRY_SCHEDULE,
) -> PlanResult:
    """The energy-driven planner behind the shared interface: ``plan_energy(problem) -> PlanResult``.

    Plans start -> goal (through ``problem.key`` when given, as two legs) with
    ``energy_interpolate``. Local minima depend on the fall-off exponent d (paper 004 section 8),
    so after a FAILED leg the other exponents of ``retry_falloffs`` are tried in turn within the
    budget. Once every leg has its legal first-stage motion, each is reduced and smoothed
    (key postures, straightening, second stage, dense output) in what is left of
    ``problem.budget_s``: each of those steps only ever replaces a legal motion by another legal
    one, so when the budget runs out they stop where they are and the motion is returned legal
    but less smooth (``stats["stopped_on_budget"]`` names the steps cut short, and a warning is
    logged). Deterministic while the budget is not reached: ``problem.seed`` is not used.

    Returns:
        PlanResult with a PostureSequence path on success, or a status and a reason.
    """
    checker = problem.checker
    robot = checker.robot
    t0 = time.monotonic()
    deadline = t0 + problem.budget_s
    gli = GliMatrix(robot, checker.model, checker.index)
    validator = MotionValidator.for_checker(checker, params.verify_resolution_m)  # one robot geometry for every step
    schedule = [params.falloff_d] + [d for d in retry_falloffs if d != params.falloff_d]
    energies: dict[int, RepulsiveEnergy] = {}
    legs = [problem.start, problem.goal] if problem.key is None else [problem.start, problem.key, problem.goal]
    first: list[tuple[np.ndarray, dict[str, Any]]] = []  # each leg's first-stage motion and its stats
    stats: dict[str, Any] = {"planner": "energy", "legs": []}
    for k in range(len(legs) - 1):
        reasons = []
        out = None
        for d in schedule:
            remaining = problem.budget_s - (time.monotonic() - t0)
            if remaining <= 0.0:
                break
            p_d = dataclasses.replace(params, falloff_d=d)
            if d not in energies:
                energies[d] = RepulsiveEnergy(checker, p_d)
            out = energy_interpolate(
                checker,
                checker.qpos_of(legs[k]),
                checker.qpos_of(legs[k + 1]),
                params=p_d,
                constraints=constraints,
                budget_s=remaining,
                energy=energies[d],
                gli=gli,
                validator=validator,
            )
            out.stats["falloff_d"] = d
            stats["legs"].append(out.stats)
            if out.status is not PlanStatus.FAILED:
                break
            reasons.append(f"d={d}: {out.reason}")
            log.info("energy planner, leg %d, d=%d failed: %s", k, d, out.reason)
        if out is None:
            out = InterpolationOutcome(PlanStatus.TIMEOUT, None, f"budget of {problem.budget_s:.1f} s spent")
        if out.status is not PlanStatus.EXACT_SOLUTION or out.qpos is None:
            status = out.status
            if status is PlanStatus.INVALID_GOAL and problem.key is not None and k == 0:
                status = PlanStatus.FAILED  # an illegal key posture: not the goal's fault
            reason = "; ".join(reasons) if status is PlanStatus.FAILED and reasons else out.reason
            stats["seconds"] = time.monotonic() - t0
            return PlanResult(status, None, f"leg {k}: {reason}" if len(legs) > 2 else reason, stats)
        first.append((out.qpos, out.stats))
    rows: list[np.ndarray] = []
    stopped: list[str] = []
    for k, (q_leg, leg_stats) in enumerate(first):
        q_leg = _refine_leg(checker, q_leg, gli, validator, params, constraints, deadline, leg_stats)
        stopped += [f"leg {k}: {step}" if len(first) > 1 else step for step in leg_stats["stopped_on_budget"]]
        rows.extend(q_leg if k == 0 else q_leg[1:])
    stats["stopped_on_budget"] = stopped
    if stopped:
        log.warning("energy planner: budget of %.3g s reached in %s; returning the legal motion as it stood (less smooth)",
                    problem.budget_s, ", ".join(stopped))
    stats["seconds"] = time.monotonic() - t0
    stats["waypoints"] = len(rows)
    postures: list[Posture] = [posture_from_qpos(robot, checker.index, q) for q in rows]
    path = PostureSequence.from_postures(postures, robot.joint_names)
    return PlanResult(PlanStatus.EXACT_SOLUTION, path, "", stats)


@dataclass(frozen=True)
class EnergyPlanner:
    """``plan_energy`` as a ``Planner`` object (for ``plan_trajectory(problem, planner=...)``)."""

    params: EnergyConfig = EnergyConfig()
    constraints: tuple[PositionalConstraint, ...] = ()

    def __call__(self, problem: PlanningProblem) -> PlanResult:
        return plan_energy(problem, params=self.params, constraints=self.constraints)
