"""Energy-descent bidirectional interpolation between two postures (paper 004 section 5.1, Algorithm 1; Algorithm 2 with constraints).

The end of higher energy steps toward the other; inside the safe zone of the Gauss linking
integral (section 5.2.2, eq. 7-8) the two ends are joined straight when that motion is legal.

Adaptations (ours, robot_rise/constants.py):

- The ground is always there, so the safe-zone rule "linear step if E_gli < 0.3 and O is empty"
  becomes "linear step if E_gli < 0.3 and the linear step is legal".
- A projected step (I - g g^T) D keeps the energy level only to first order; we add a small
  descent component -beta g so the energy of the moving end really decreases (as Algorithm 1's
  expansion toward the canonical postures of section 5.1 intends).
- Every accepted step is checked, and the final path is verified at a fixed travel resolution
  by the shared segment checker (robot_rise.planning.motion_validator).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from robot_rise.planning.energy.config import EnergyConfig
from robot_rise.planning.energy.constraints import PositionalConstraint, StepConstraints, project_constraints, with_ground_contacts
from robot_rise.planning.energy.gli import GliMatrix, gli_difference
from robot_rise.planning.energy.repulsive import RepulsiveEnergy
from robot_rise.planning.energy.tangent import tangent_difference, tangent_scale, tangent_step
from robot_rise.planning.energy.window import EnergyWindow
from robot_rise.planning.motion_validator import MotionValidator
from robot_rise.planning.problem import PlanStatus
from robot_rise.validity import ValidityChecker

__all__ = ["InterpolationOutcome", "energy_interpolate"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class InterpolationOutcome:
    """Result of ``energy_interpolate``.

    Attributes:
        status: EXACT_SOLUTION, FAILED (local minimum / blocked / verification), TIMEOUT, INVALID_*.
        qpos: the path as qpos rows of the checker's model, shape (K, nq) (None on failure).
        reason: why it failed; empty on success.
        stats: counters (iterations, linear/projected/constrained steps, energies, seconds).
    """

    status: PlanStatus
    qpos: np.ndarray | None
    reason: str = ""
    stats: dict[str, Any] = field(default_factory=dict)


def energy_interpolate(
    checker: ValidityChecker,
    qpos_start: np.ndarray,
    qpos_goal: np.ndarray,
    *,
    params: EnergyConfig = EnergyConfig(),
    constraints: tuple[PositionalConstraint, ...] = (),
    budget_s: float = 30.0,
    energy: RepulsiveEnergy | None = None,
    gli: GliMatrix | None = None,
    validator: MotionValidator | None = None,
) -> InterpolationOutcome:
    """Energy-based bidirectional interpolation (paper 004 Algorithm 1; Algorithm 2 with constraints).

    Each iteration moves the end of higher energy, P_h, toward the other, P_l, by one step of
    length alpha in the scaled tangent space: linearly inside the safe zone (eq. 8), else along
    D = (P_l - P_h)/|P_l - P_h| if that does not raise the energy, else along the projection
    (I - g g^T) D with a little descent (eq. 5). Joint limits and positional constraints are
    enforced by the null-space projections of eq. (10)-(11). Every accepted posture is legal for
    ``checker``; when the two ends can be joined by a legal straight motion they are, and the
    whole path M_1 + reverse(M_2) is verified at ``params.verify_resolution_m``.

    Args:
        checker: the strict validity checker (robot + scene).
        qpos_start, qpos_goal: qpos of the checker's model, shape (nq,).
        params: energy and algorithm parameters.
        constraints: positional constraints kept along the whole path (Algorithm 2).
        budget_s: wall-clock budget [s].
        energy, gli, validator: reuse prebuilt objects (they are rebuilt from the checker otherwise;
            the segment checker's resolution is set to ``params.verify_resolution_m``).

    Returns:
        InterpolationOutcome; failures carry a status and a reason, never an exception.
    """
    t0 = time.monotonic()
    p = params
    m = checker.model
    if not checker.is_valid_qpos(qpos_start):
        return InterpolationOutcome(PlanStatus.INVALID_START, None, "start: " + "; ".join(checker.check_qpos(qpos_start).reasons()))
    if not checker.is_valid_qpos(qpos_goal):
        return InterpolationOutcome(PlanStatus.INVALID_GOAL, None, "goal: " + "; ".join(checker.check_qpos(qpos_goal).reasons()))
    energy = energy if energy is not None else RepulsiveEnergy(checker, p)
    gli = gli if gli is not None else GliMatrix(checker.robot, m, checker.index)
    scale = tangent_scale(checker, p.root_translation_scale_m)
    cons = StepConstraints(checker, constraints, scale)
    res = p.verify_resolution_m
    validator = MotionValidator.for_checker(checker, res) if validator is None else validator.with_resolution(res)
    root = np.asarray(checker.index.qvel_root)
    alpha = p.step_rad

    ends = [np.array(qpos_start, dtype=float), np.array(qpos_goal, dtype=float)]
    paths: list[list[np.ndarray]] = [[ends[0].copy()], [ends[1].copy()]]
    evals = [energy(ends[0]), energy(ends[1])]
    glis = [gli(ends[0]), gli(ends[1])]
    window = EnergyWindow(max(evals[0].total, evals[1].total), p.window_fraction, p.patience)
    stats: dict[str, Any] = {
        "iterations": 0,
        "direct_steps": 0,
        "projected_steps": 0,
        "descent_steps": 0,
        "constrained_steps": 0,
        "contact_steps": 0,
        "rejected_steps": 0,
        "connect_attempts": 0,
        "safe_zone_refuted": 0,
        "energy_start": evals[0].total,
        "energy_goal": evals[1].total,
    }

    def finish(status: PlanStatus, reason: str, q: np.ndarray | None) -> InterpolationOutcome:
        stats["seconds"] = time.monotonic() - t0
        return InterpolationOutcome(status, q, reason, stats)

    last_connect_gap = math.inf
    for it in range(p.max_iterations):
        stats["iterations"] = it + 1
        if time.monotonic() - t0 > budget_s:
            return finish(PlanStatus.TIMEOUT, f"budget of {budget_s:.1f} s spent after {it} iterations", None)
        v_gap = tangent_difference(m, ends[0], ends[1])
        gap = float(np.linalg.norm(scale * v_gap))
        e_gli = gli_difference(glis[0], glis[1])
        safe = p.use_safe_zone and e_gli < p.gli_threshold
        # section 5.2.2: inside the safe zone, f = f1 + lerp(P1e, P2e) + f2. We ask the checker
        # whether the straight motion between the ends is legal instead of trusting eq. (8) alone
        # (short, thick robot links can stay under the threshold while crossed); tried again
        # whenever the gap shrank by a fifth, and always within one step
        # (with positional constraints only within one step: a long straight motion ignores them)
        if gap <= alpha or (safe and not constraints and gap < 0.8 * last_connect_gap):
            stats["connect_attempts"] += 1
            last_connect_gap = gap
            if validator.qpos_segment_valid(ends[0], ends[1]):
                path = np.array(paths[0] + paths[1][::-1])
                return _verified(validator, path, finish, stats)
            if safe:
                stats["safe_zone_refuted"] += 1  # eq. (8) said safe, the checker said no
        h = 0 if evals[0].total >= evals[1].total else 1
        lo = 1 - h
        qh = ends[h]
        D = scale * tangent_difference(m, qh, ends[lo])
        D_hat = D / max(float(np.linalg.norm(D)), 1e-12)
        g = evals[h].gradient / scale
        if not p.move_root:
            g = g.copy()
            g[root] = 0.0
        g_norm = float(np.linalg.norm(g))
        g_hat = g / g_norm if g_norm > 1e-12 else np.zeros_like(g)

        accepted = False
        # Attempts, in order: the paper's step (D if it does not climb, else eq. 5), then more and
        # more descent (a rejected step collided or climbed: move away from the nearest links),
        # then pure descent (eq. 4) at halving lengths. Algorithm 1 steps linearly inside the safe
        # zone only when there is no environment (O empty); the ground is always there, so the
        # safe zone here only triggers the straight connection above.
        proj = D_hat - g_hat * float(g_hat @ D_hat)  # eq. (5): (I - g g^T) D
        plan: list[tuple[str, np.ndarray]] = []
        if float(D_hat @ g_hat) <= 0.0:
            plan.append(("direct_steps", D_hat * min(alpha, gap)))
        for beta in (p.descent_beta, 1.0, 3.0):
            plan.append(("projected_steps", alpha * (proj - beta * g_hat)))
        for frac in (1.0, 0.5, 0.25, 0.125):
            plan.append(("descent_steps", -alpha * frac * g_hat))
        # then the same attempts again with the touched ground as positional constraints (Algorithm 2)
        plan_all = [(kind, dy, False) for kind, dy in plan] + ([(kind, dy, True) for kind, dy in plan] if p.ground_contacts else [])
        for attempt, (kind, dy, contact) in enumerate(plan_all):
            if not np.any(dy):
                continue
            K, C = cons.rows(qh, dy)
            if contact:
                K, C = with_ground_contacts(energy, qh, dy, K, C, g_hat, scale, p)
                if K.shape[0] == cons.rows(qh, dy)[0].shape[0]:
                    continue  # no contact in the way: the plain attempt already said no
            constrained = K.shape[0] > 0
            if constrained:  # Algorithm 2: project onto the constraints' null space
                dy = project_constraints(dy, K, C, g_hat, p)
            q_new = tangent_step(m, qh, dy / scale)
            # eq. (13) as a hard bound: the least-squares projection leaves residuals of ~1e-6 rad
            qj = checker.index.qpos_joints
            q_new[qj] = np.clip(q_new[qj], checker.robot.joint_lower, checker.robot.joint_upper)
            valid = checker.is_valid_qpos(q_new)
            if log.isEnabledFor(logging.DEBUG):
                log.debug(
                    "it %d side %d attempt %d %s |dy| %.4f D.g %.3f valid %s E_h %.4g E_new %.4g",
                    it, h, attempt, kind, float(np.linalg.norm(dy)), float(D_hat @ g_hat), valid,
                    evals[h].total, energy(q_new, gradient=False).total,
                )
                if not valid:
                    log.debug("  invalid: %s", "; ".join(checker.check_qpos(q_new).reasons()))
            if valid:
                e_new = energy(q_new)
                # a step must not climb (energy barrier of section 4.2), up to a 0.1 % tolerance
                if e_new.total <= evals[h].total * (1.0 + 1e-3):
                    accepted = True
                    break
            stats["rejected_steps"] += 1
        if not accepted:
            return finish(
                PlanStatus.FAILED,
                f"blocked: no legal energy-non-increasing step from the {'start' if h == 0 else 'goal'} side after {it} iterations",
                None,
            )
        stats[kind] += 1
        stats["constrained_steps"] += int(constrained)
        stats["contact_steps"] += int(contact)
        ends[h] = q_new
        evals[h] = e_new
        glis[h] = gli(q_new)
        paths[h].append(q_new)
        e_low = min(evals[0].total, evals[1].total)
        log.debug("it %d moved %d by %s: E %.4g / %.4g, gap %.3f, E_gli %.3f", it, h, kind, evals[0].total, evals[1].total, gap,
                  gli_difference(glis[0], glis[1]))
        if window.update(e_low, gap, 0.1 * alpha):
            return finish(
                PlanStatus.FAILED,
                f"local minimum (paper 004 section 8): energies {evals[0].total:.4g} / {evals[1].total:.4g} and gap "
                f"{gap:.3f} rad stayed in one window for {p.patience} iterations",
                None,
            )
    return finish(PlanStatus.FAILED, f"no meeting after {p.max_iterations} iterations", None)


def _verified(
    validator: MotionValidator,
    path: np.ndarray,
    finish: Callable[[PlanStatus, str, np.ndarray | None], InterpolationOutcome],
    stats: dict[str, Any],
) -> InterpolationOutcome:
    """Verify every segment of the path at the fine resolution (steps can skip thin contacts)."""
    for k in range(len(path) - 1):
        if not validator.qpos_segment_valid(path[k], path[k + 1]):
            return finish(PlanStatus.FAILED, f"verification: segment {k} of {len(path) - 1} is illegal at {validator.resolution_m} m", None)
    stats["waypoints"] = len(path)
    return finish(PlanStatus.EXACT_SOLUTION, "", path)
