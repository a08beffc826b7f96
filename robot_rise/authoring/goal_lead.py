"""Goal-lead clamping: the goals of a saturating (momentum) motion pulled back to what the servos can follow within the envelope.

Motions that need their momentum (``MotionSpec.retime=False``, ``clamp_lead=True``:
supine_situp_rock_robust, prone_elbow_knees_quick) keep their searched keyframe times;
:func:`clamp_goal_lead` cuts their torque peaks on all five robustness players instead, and (with
``spread_starts``) from the rest states a composed get-up may arrive in
(``robot_rise.filter.arrival_spread_starts``).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

from robot_rise.proof.composed import ARRIVAL_SETTLE_S, settled_start
from robot_rise.model import Robot
from robot_rise.posture import Posture
from robot_rise.servo import servo_arrays
from robot_rise.sim.player import Player, Recording
from robot_rise.trajectory import Trajectory

__all__ = [
    "LEAD_CLAMP_MAX_ITER",
    "LEAD_CLAMP_RATIO",
    "LEAD_CLAMP_STEP",
    "LEAD_CLAMP_TARGET",
    "LEAD_CLAMP_WARM_ITER",
    "LEAD_CLAMP_WINDOW_S",
    "clamp_goal_lead",
]

log = logging.getLogger(__name__)

LEAD_CLAMP_RATIO = 0.85  # clamp_goal_lead: goals lead the servo by at most the error giving this ratio of the envelope
LEAD_CLAMP_TARGET = 0.87  # clamp_goal_lead: done when every player's peak torque / envelope is at most this (bound 0.9)
LEAD_CLAMP_WARM_ITER = 12  # clamp_goal_lead: iterations at the uniform ratio before it is lowered locally
LEAD_CLAMP_MAX_ITER = 40  # clamp_goal_lead: iterations (each plays every player once)
LEAD_CLAMP_WINDOW_S = 0.05  # clamp_goal_lead: a violation lowers the ratio of that joint within this window [s]
LEAD_CLAMP_STEP = 0.02  # clamp_goal_lead: how much a violation lowers the local ratio per iteration

def clamp_goal_lead(
    robot: Robot,
    trajectory: Trajectory,
    players: Sequence[Player],
    *,
    ratio: float = LEAD_CLAMP_RATIO,
    target: float = LEAD_CLAMP_TARGET,
    warm_iter: int = LEAD_CLAMP_WARM_ITER,
    max_iter: int = LEAD_CLAMP_MAX_ITER,
    window_s: float = LEAD_CLAMP_WINDOW_S,
    step: float = LEAD_CLAMP_STEP,
    spread_starts: Sequence[Posture] = (),
    settle_s: float = ARRIVAL_SETTLE_S,
) -> Trajectory:
    """Pull the goals of a saturating motion back to what the servos can follow within the envelope.

    A dynamic motion (one that uses momentum) is easiest to author with goals far ahead of the
    joints: the servos saturate (ratio 1). In position mode the torque is
    ``tau = tau_stall * (clip(kp e / tau_stall) - w / w0)`` with ``e`` the goal error, so the
    ratio ``r`` of the envelope is kept by ``e`` in
    ``[(-r + (1 - r) w / w0), (r + (1 - r) w / w0)] * tau_stall / kp`` (``+`` side: room
    ``tau_stall (1 - w / w0)``, braking side: ``tau_stall (1 + w / w0)``). Each iteration plays
    the motion on every player, and clips each authored goal into the intersection over the
    players of ``q(t) + [e_min, e_max]`` at the simulated joint angle ``q`` and speed ``w``; the
    motion is then played again (the joints move less fast with less torque) until it converges.
    After ``warm_iter`` iterations, wherever a player still exceeds ``target`` (impacts, fast
    speed changes within a row), the ratio of that joint within ``window_s`` is lowered by
    ``step``. The motion keeps its timing: only the torque peaks are cut.

    Args:
        trajectory: the authored motion (rows at ``robot_rise.authoring.keyframes.ROW_HZ``), joint goals [rad].
        players: nominal and the friction/mass corners.
        spread_starts: start postures the nominal player (``players[0]``) also plays the motion
            from, after ``settle_s`` on its first targets (a composed get-up's arrival): their
            torque in the motion is clamped too, so that joining the motion from rest does not
            exceed the envelope where its own start does not.
        settle_s: the hold on the first targets before the motion from a spread start [s].

    Returns:
        the clamped trajectory (same rows, new goals; the first row unchanged). The caller verifies it.
    """
    sv = servo_arrays(robot.servo_datasheets(), robot.supply_voltage_v)
    kp, stall, w0 = sv.kp_nm_per_rad, sv.stall_torque_nm, sv.no_load_speed_rad_s
    t = trajectory.t
    base = trajectory.q
    goals = base.copy()
    r = np.full(base.shape, ratio)
    n = base.shape[1]
    for it in range(max_iter):
        cur = Trajectory(trajectory.robot, trajectory.joint_names, t, goals, trajectory.start)
        lo = np.full(base.shape, -np.inf)
        hi = np.full(base.shape, np.inf)
        over = np.zeros(base.shape, dtype=bool)
        peaks = []
        plays: list[tuple[Recording, float]] = [(player.play(cur), 0.0) for player in players]
        if spread_starts:
            settled = settled_start(cur, settle_s)
            plays += [(players[0].play(settled, s), settle_s) for s in spread_starts]
        for rec, shift in plays:
            rt = rec.t - shift  # the motion's clock (a spread start's settle before it)
            moving = rt > 0.0
            peaks.append(rec.peak_envelope_ratio if not shift else float(np.max(rec.envelope_ratio[moving], initial=0.0)))
            q = np.stack([np.interp(t, rt, rec.q[:, j]) for j in range(n)], axis=-1)
            w = np.stack([np.interp(t, rt, rec.qd[:, j]) for j in range(n)], axis=-1)
            lo = np.maximum(lo, q + (-r + (1 - r) * w / w0) * stall / kp)
            hi = np.minimum(hi, q + (r + (1 - r) * w / w0) * stall / kp)
            for k, j in np.argwhere((rec.envelope_ratio > target) & moving[:, None]):
                over[np.abs(t - rt[k]) <= window_s, j] = True
        log.info("clamp_goal_lead %d: peaks %s", it, " ".join(f"{p:.3f}" for p in peaks))
        if max(peaks) <= target:
            break
        if it >= warm_iter:
            r = np.where(over, r - step, r)
        empty = lo > hi  # the players disagree: split the difference
        mid = 0.5 * (lo + hi)
        goals = np.clip(base, np.where(empty, mid, lo), np.where(empty, mid, hi))
        goals[0] = base[0]
    return Trajectory(trajectory.robot, trajectory.joint_names, t, goals, trajectory.start)
