"""Get-up planners for the live loop: plan (and prove) a get-up from an estimated lying posture.

:class:`RisePlanner` is ours (``rise`` with a per-robot precomputed context, proven get-ups);
:class:`KeyframePlanner` is the stock OP3's scheme for comparison (a front and a back keyframe
get-up, unproven).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from robot_rise.filter import FilterConfig
from robot_rise.library import MotionLibrary
from robot_rise.live.estimate import PostureEstimate
from robot_rise.model import Robot
from robot_rise.rise import RiseContext, RiseOptions, rise
from robot_rise.start_repair import RepairConfig, StartRepair, repair_start
from robot_rise.trajectory import Trajectory

__all__ = ["PlannedGetUp", "GetUpPlanner", "RisePlanner", "KeyframePlanner"]


@dataclass(frozen=True)
class PlannedGetUp:
    """A get-up for the present posture, or why there is none.

    Attributes:
        trajectory: servo targets from the estimated posture (None: none found).
        proven: the trajectory carries a proof (only proven trajectories are executed).
        reason: why not proven (empty when proven).
        motion: the library motion it ends in.
        start_repair: how the estimated posture was made a valid start (None: not checked, as
            by the keyframe planner; ``status`` VALID: nothing changed).
    """

    trajectory: Trajectory | None
    proven: bool
    reason: str = ""
    motion: str = ""
    start_repair: StartRepair | None = None


class GetUpPlanner(Protocol):
    """Plans and proves a get-up from an estimated lying posture."""

    def plan(self, estimate: PostureEstimate, attempt: int) -> PlannedGetUp: ...


class RisePlanner:
    """:func:`robot_rise.rise.rise` with a per-robot precomputed :class:`RiseContext`.

    The first proven candidate is returned (anytime in candidates: nearest library motion first;
    a proof includes the ensemble). ``retries`` is 0 by default: a failed get-up is retried on the
    robot, from where it really lies, not in simulation.

    A robot lying somewhere is a valid start: an estimate that self-collides or sinks a few mm in
    our model is repaired first (:func:`robot_rise.start_repair.repair_start`: joints nudged
    apart, root lifted), and the repair is reported in :attr:`PlannedGetUp.start_repair`.

    Args:
        context: checker, library, frame index, K-means tree and the ensemble's players.
        budget_s: planning budget per candidate [s].
        candidates: library motions tried, nearest first.
        retries: rise's own in-simulation retries.
        filter_config: the dynamics filter (ensemble proof on by default).
        composed: compose the ensemble proof with the library motions' start proofs where it
            applies (``robot_rise.proof.composed``; precompute them: ``RiseContext.warm_start_proofs``).
        repair: bounds of the start repair.
    """

    def __init__(self, context: RiseContext, *, budget_s: float = 5.0, candidates: int = 3, retries: int = 0,
                 filter_config: FilterConfig = FilterConfig(), composed: bool = False,
                 repair: RepairConfig = RepairConfig()) -> None:
        self.context = context
        self.repair = repair
        self.composed = composed
        self.budget_s = budget_s
        self.candidates = candidates
        self.retries = retries
        self.filter_config = filter_config

    def plan(self, estimate: PostureEstimate, attempt: int) -> PlannedGetUp:
        ctx = self.context
        repaired = repair_start(estimate.posture, ctx.checker, config=self.repair)
        if not repaired.valid:
            return PlannedGetUp(None, False, repaired.describe(), start_repair=repaired)
        options = RiseOptions(scene=ctx.scene, seed=attempt, budget_s=self.budget_s, candidates=self.candidates, retries=self.retries,
                              filter_config=self.filter_config, composed=self.composed)
        result = rise(ctx.robot, repaired.posture, options, context=ctx)
        motion = str(result.trajectory.report.get("motion", "")) if result.trajectory is not None else ""
        return PlannedGetUp(result.trajectory if result.proven else None, result.proven, result.reason, motion,
                            start_repair=repaired)


class KeyframePlanner:
    """The stock OP3's scheme, for comparison: one keyframe get-up for the front, one for the back.

    The ROBOTIS OP3 plays a fixed action page per side (front or back) from wherever the robot
    lies, first moving every joint to the page's first pose. Here the library's motion for that
    side stands in for the page, after a ``move_s`` joint-space move from the present angles to
    its first frame. Nothing is planned or proven (execute with ``GetUpConfig.execute_unproven``);
    a robot on its side has no keyframe.

    Args:
        robot: the robot.
        library: its motion library.
        front: motion played lying prone (default: the library's fastest prone get-up).
        back: motion played lying supine.
        move_s: [s] the move to the motion's first frame (the OP3's action module interpolates
            to the first page pose over about a second).
    """

    def __init__(self, robot: Robot, library: MotionLibrary, *, front: str = "prone_elbow_knees_quick",
                 back: str = "supine_backroll_kneel", move_s: float = 1.0) -> None:
        self.robot = robot
        self.motions = {"prone": library.get(front), "supine": library.get(back)}
        self.move_s = move_s

    def plan(self, estimate: PostureEstimate, attempt: int) -> PlannedGetUp:
        motion = self.motions.get(estimate.lying or "")
        if motion is None:
            return PlannedGetUp(None, False, f"no keyframe get-up lying {estimate.lying or 'upright'}")
        tr = motion.trajectory
        names = self.robot.joint_names
        cols = [tr.joint_names.index(j) for j in names]
        q0 = estimate.posture.joint_vector(names)
        t = np.concatenate([[0.0], self.move_s + (tr.t - tr.t[0])])
        q = np.vstack([q0, tr.q[:, cols]])
        traj = Trajectory(self.robot.name, names, t, q, estimate.posture,
                          {"motion": motion.name, "scheme": "stock OP3 keyframe (not proven from here)"})
        return PlannedGetUp(traj, False, "keyframe, not proven from where the robot lies", motion.name)
