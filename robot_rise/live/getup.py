"""The live get-up loop, as plain functions over the :class:`~robot_rise.live.io.RobotIO` interface.

:func:`get_up` (one shot from the present state)::

    watch the IMU until fallen-and-still (FallTracker: FALLEN)   -- or STANDING: nothing to do
    for each attempt (at most ``attempts``):
        check health (temperatures, voltage, hardware errors)    -- a problem: go limp, give up
        estimate where the body lies (joint angles + IMU gravity)
        plan and prove a get-up from there (GetUpPlanner: rise with a per-robot RiseContext)
        execute it (the executor's own safety layer watches it)
        confirm standing from the IMU: upright and still for ``confirm_s``
        standing: done; else go limp, wait until still again, next attempt
    give up safely: limp, with a report of every attempt

The stock OP3's scheme runs in the same loop for comparison:
:class:`~robot_rise.live.planners.KeyframePlanner` (a front and a back keyframe get-up, unproven)
with ``GetUpConfig(limp_when_falling=False, fallen_pitch_deg=60, execute_unproven=True)``.

Time: every time is on the IO's clock (see :mod:`robot_rise.live.io`); thinking's CPU time is
handed to ``RobotIO.spent``.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from robot_rise.live.estimate import PostureEstimate, PostureEstimator
from robot_rise.live.fall import FallConfig, FallState, FallTracker, new_tracker, step
from robot_rise.live.health import HealthLimits, health_problems
from robot_rise.live.io import RobotIO, TruthSource
from robot_rise.live.planners import GetUpPlanner, PlannedGetUp
from robot_rise.start_repair import StartRepair

__all__ = [
    "GetUpConfig",
    "pitch_deg",
    "fallen_by_config",
    "AttemptReport",
    "GetUpReport",
    "watch",
    "Confirmation",
    "confirm_standing",
    "get_up",
]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class GetUpConfig:
    """Settings of :func:`get_up` (ours).

    Attributes:
        attempts: tries at most, each from where the robot then lies.
        cycle_s: [s] period of the IMU loop (100 Hz, the executor's rate).
        wait_still_s: [s] longest wait for the robot to lie still (or stand) before a try.
        confirm_s: [s] upright and still this long after a get-up counts as standing (the
            standing judge asks for 2 s of the proof's hold; the IMU's 1 s of upright and still,
            with the servos holding, is the robot's own evidence).
        confirm_timeout_s: [s] no standing by then after the trajectory ended: not standing.
        hold_before_s: [s] before a try the servos hold the lying posture (a limp limb drifts
            under gravity while the get-up is thought out: the OP3 twin's head moved 0.2 rad in
            3 s, twice the executor's start tolerance) at least this long before the first
            command, while the get-up is thought out. The joints are read as torque comes on,
            before the held limbs sag onto their loads: the proof's replay starts from rest at
            those angles with the servos holding them, and sags the same way.
        imu_lost_after: invalid IMU samples in a row after which the loop stops (limp).
        health: when not to try.
        fall: the fall detector's thresholds.
        limp_when_falling: go limp while falling and once lying (ours); False: the servos keep
            their goals (the stock OP3).
        fallen_pitch_deg: None: fallen in every direction (ours). A number [deg]: fallen only
            when the torso pitch is past it, front or back (the stock OP3's test is 60 deg): a
            robot on its side is not fallen.
        execute_unproven: execute a planner's unproven trajectory (the stock OP3's keyframes,
            :class:`KeyframePlanner`); ours executes proven get-ups only.
    """

    attempts: int = 3
    cycle_s: float = 0.01
    wait_still_s: float = 10.0
    confirm_s: float = 1.0
    confirm_timeout_s: float = 5.0
    hold_before_s: float = 0.15
    imu_lost_after: int = 50
    health: HealthLimits = HealthLimits()
    fall: FallConfig = FallConfig()
    limp_when_falling: bool = True
    fallen_pitch_deg: float | None = None
    execute_unproven: bool = False

    def __post_init__(self) -> None:
        if self.fallen_pitch_deg is not None and not 0.0 < self.fallen_pitch_deg < 90.0:
            raise ValueError(f"GetUpConfig.fallen_pitch_deg must be in (0, 90), got {self.fallen_pitch_deg}")
        if self.attempts < 1:
            raise ValueError(f"GetUpConfig.attempts must be >= 1, got {self.attempts}")
        for name in ("cycle_s", "wait_still_s", "confirm_s", "confirm_timeout_s", "hold_before_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"GetUpConfig.{name} must be finite and > 0, got {value}")
        if self.imu_lost_after < 1:
            raise ValueError(f"GetUpConfig.imu_lost_after must be >= 1, got {self.imu_lost_after}")


@dataclass(frozen=True)
class AttemptReport:
    """One try.

    Attributes:
        attempt: 1-based.
        started_s: IO time the try began (health check) [s].
        fallen_s: IO time fallen-and-still was detected for this try [s].
        lying: the lying kind the IMU shows (None: not lying).
        health: reasons not to move found before the try (empty: healthy).
        estimate: where the body was estimated to lie (None: not estimated).
        estimate_cpu_s, plan_cpu_s: CPU time of the estimate and of plan + proof [s].
        start_repair: how the estimate was made a valid start (None: the planner did not check;
            ``describe()`` says what was changed: root lifted, joints nudged apart).
        proven: a proven get-up was found.
        motion: the library motion it ends in.
        first_command_s: IO time of the first goal of the get-up [s] (None: nothing sent).
        executed: the trajectory ran to its end without a fault.
        ended_s: IO time the try ended (standing confirmed or given up on) [s].
        standing: standing confirmed from the IMU.
        standing_s: IO time standing was confirmed [s].
        why: why not standing (empty when standing).
    """

    attempt: int
    started_s: float
    fallen_s: float | None
    lying: str | None
    health: tuple[str, ...] = ()
    estimate: PostureEstimate | None = None
    estimate_cpu_s: float = 0.0
    plan_cpu_s: float = 0.0
    start_repair: StartRepair | None = None
    proven: bool = False
    motion: str = ""
    first_command_s: float | None = None
    executed: bool = False
    ended_s: float = math.nan
    standing: bool = False
    standing_s: float | None = None
    why: str = ""

    @property
    def first_command_after_s(self) -> float | None:
        """From fallen-and-still to the first command [s]."""
        if self.first_command_s is None or self.fallen_s is None:
            return None
        return self.first_command_s - self.fallen_s

    def to_dict(self) -> dict[str, Any]:
        e = self.estimate
        return {
            "attempt": self.attempt,
            "started_s": self.started_s,
            "fallen_s": self.fallen_s,
            "lying": self.lying,
            "health": list(self.health),
            "estimate": None if e is None else {
                "lying": e.lying, "imu_change_deg": e.imu_change_deg, "settled": e.settled, "valid": e.valid,
                "error": None if e.error is None else e.error.to_dict()},
            "estimate_cpu_s": self.estimate_cpu_s,
            "plan_cpu_s": self.plan_cpu_s,
            "start_repair": None if self.start_repair is None else {
                **self.start_repair.to_dict(), "summary": self.start_repair.describe()},
            "proven": self.proven,
            "motion": self.motion,
            "first_command_s": self.first_command_s,
            "first_command_after_s": self.first_command_after_s,
            "executed": self.executed,
            "ended_s": self.ended_s,
            "standing": self.standing,
            "standing_s": self.standing_s,
            "why": self.why,
        }


@dataclass(frozen=True)
class GetUpReport:
    """Outcome of :func:`get_up`.

    Attributes:
        standing: the robot stands (confirmed from the IMU) at the end.
        attempts: every try, in order (empty when it was standing already or never lay still).
        reason: why it is not standing (empty when standing).
        gave_up: it stopped trying and went limp.
        already_standing: it was standing when asked: nothing was done.
        interrupted: the operator stopped it.
        tracker: the fall detector at the end (the guard goes on from it).
    """

    standing: bool
    attempts: tuple[AttemptReport, ...]
    reason: str = ""
    gave_up: bool = False
    already_standing: bool = False
    interrupted: bool = False
    tracker: FallTracker = field(default_factory=new_tracker, repr=False)

    @property
    def standing_s(self) -> float | None:
        """IO time standing was confirmed [s] (None: not standing after a try)."""
        return next((a.standing_s for a in self.attempts if a.standing), None)

    def to_dict(self) -> dict[str, Any]:
        return {"standing": self.standing, "gave_up": self.gave_up, "already_standing": self.already_standing,
                "interrupted": self.interrupted, "reason": self.reason,
                "attempts": [a.to_dict() for a in self.attempts]}


def watch(io: RobotIO, tracker: FallTracker, *, until: Iterable[FallState], timeout_s: float, cycle_s: float,
          imu_lost_after: int = 50) -> tuple[FallTracker, str]:
    """Read the IMU every ``cycle_s`` until the detector's state is one of ``until``.

    Returns:
        (the detector, why not): why is empty when the state was reached; else it says so after
        ``timeout_s`` [s], or after ``imu_lost_after`` unusable samples in a row (it then begins
        with "the IMU").
    """
    wanted = frozenset(until)
    if tracker.state in wanted:
        return tracker, ""
    t_end = io.now_s() + timeout_s
    bad = 0
    while io.now_s() < t_end:
        nxt = step(tracker, io.read_imu())
        bad = bad + 1 if nxt is tracker else 0
        tracker = nxt
        if tracker.state in wanted:
            return tracker, ""
        if bad >= imu_lost_after:
            return tracker, f"the IMU stopped answering ({bad} reads in a row failed)"
        io.sleep(cycle_s)
    names = " or ".join(sorted(st.value for st in wanted))
    return tracker, f"not {names} within {timeout_s:.0f} s (the detector reads {tracker.state.value})"


@dataclass(frozen=True)
class Confirmation:
    """What :func:`confirm_standing` saw.

    Attributes:
        tracker: the detector at the end.
        standing: upright and still for ``confirm_s``.
        standing_s: IO time standing was confirmed [s] (None: not standing).
        why: why not standing (empty when standing).
        imu_lost: the IMU stopped answering: nothing is known (the servos are left holding).
    """

    tracker: FallTracker
    standing: bool
    standing_s: float | None = None
    why: str = ""
    imu_lost: bool = False


def confirm_standing(io: RobotIO, tracker: FallTracker, config: GetUpConfig) -> Confirmation:
    """After a get-up: standing once upright (tilt below ``fall.upright_tilt_rad``) for
    ``confirm_s`` and still for ``fall.still_s``; not standing when it lies still again, or after
    ``confirm_timeout_s``. A get-up that topples is let go limp (no fighting the impact)."""
    fall = config.fall
    t0 = io.now_s()
    bad = 0
    limp = False
    while io.now_s() - t0 < config.confirm_timeout_s:
        nxt = step(tracker, io.read_imu())
        bad = bad + 1 if nxt is tracker else 0
        tracker = nxt
        now = tracker.estimate.t_s
        if bad >= config.imu_lost_after:
            return Confirmation(tracker, False, None, f"the IMU stopped answering ({bad} reads in a row failed)", True)
        if bad:  # nothing new: the detector's state is from before
            io.sleep(config.cycle_s)
            continue
        e = tracker.estimate
        if (tracker.upright_since_s is not None and now - tracker.upright_since_s >= config.confirm_s
                and e.still_s >= fall.still_s):
            return Confirmation(tracker, True, now)
        if (config.limp_when_falling and not limp and e.tilt_rad > fall.fall_tilt_rad
                and e.tilt_rate_rad_s > fall.fall_tilt_rate_rad_s):
            io.go_limp()  # toppling: do not fight the impact
            limp = True
        if tracker.state is FallState.FALLEN:
            return Confirmation(tracker, False, None, f"lying {e.lying or 'down'} again")
        io.sleep(config.cycle_s)
    tilt = math.degrees(tracker.estimate.tilt_rad)
    return Confirmation(tracker, False, None,
                        f"not upright and still {config.confirm_timeout_s:.0f} s after the motion (tilt {tilt:.0f} deg)")


def pitch_deg(tracker: FallTracker) -> float:
    """Torso pitch from the detector's up direction [deg]: + front down (prone at +90), - back down."""
    up = np.asarray(tracker.estimate.up_torso, dtype=float)
    forward = np.asarray(tracker.axes.forward, dtype=float)
    if not np.all(np.isfinite(up)):
        return math.nan
    return math.degrees(math.asin(max(-1.0, min(1.0, -float(up @ forward)))))


def fallen_by_config(tracker: FallTracker, config: GetUpConfig) -> bool:
    """The detector's FALLEN, narrowed to the stock OP3's pitch test when configured."""
    if tracker.state is not FallState.FALLEN:
        return False
    return config.fallen_pitch_deg is None or abs(pitch_deg(tracker)) > config.fallen_pitch_deg


def _read_for(io: RobotIO, tracker: FallTracker, config: GetUpConfig, duration_s: float) -> FallTracker:
    """Feed the detector for ``duration_s`` [s] (after going limp the limbs slump: a slump that
    turns the torso ends FALLEN, so the next try waits until it is still again)."""
    t0 = io.now_s()
    while io.now_s() - t0 < duration_s:
        tracker = step(tracker, io.read_imu())
        io.sleep(config.cycle_s)
    return tracker


def get_up(io: RobotIO, planner: GetUpPlanner, estimator: PostureEstimator, *,
           config: GetUpConfig = GetUpConfig(), tracker: FallTracker | None = None,
           truth: TruthSource | None = None, cpu_clock: Callable[[], float] = time.process_time) -> GetUpReport:
    """Get up from the present state (see the module docstring): at most ``config.attempts`` tries.

    Args:
        io: the robot.
        planner: plans and proves a get-up from an estimated posture.
        estimator: estimates the lying posture (per robot, reused).
        config: attempts, timings, health limits, fall thresholds.
        tracker: the fall detector as the caller left it (the guard's); default: a fresh one,
            which first watches the IMU until the robot lies still (or stands).
        truth: where the body truly lies (the twin): each estimate then carries its error.
        cpu_clock: CPU time [s] of thinking (estimate, plan, proof), handed to ``io.spent``.

    Returns:
        the report; the robot ends standing (servos holding) or limp.
    """
    tracker = tracker if tracker is not None else new_tracker(config.fall)
    attempts: list[AttemptReport] = []
    lagged: tuple[str, ...] = ()  # the joints the previous get-up stopped for

    def give_up(reason: str, *, interrupted: bool = False, limp: bool = True) -> GetUpReport:
        if limp and not interrupted:
            io.go_limp()
        log.warning("get-up: giving up: %s", reason)
        return GetUpReport(False, tuple(attempts), reason, gave_up=not interrupted, interrupted=interrupted,
                           tracker=tracker)

    try:
        for k in range(1, config.attempts + 1):
            tracker, why = watch(io, tracker, until=(FallState.FALLEN, FallState.STANDING),
                                 timeout_s=config.wait_still_s, cycle_s=config.cycle_s,
                                 imu_lost_after=config.imu_lost_after)
            if why:
                return give_up(why)
            if tracker.state is FallState.STANDING:
                if not attempts:
                    return GetUpReport(True, (), already_standing=True, tracker=tracker)
                return GetUpReport(True, tuple(attempts), tracker=tracker)
            if not fallen_by_config(tracker, config):  # the stock OP3's pitch test does not see it
                reason = (f"lying {tracker.estimate.lying or 'down'} with the torso pitched {pitch_deg(tracker):.0f} deg: "
                          f"not fallen by the pitch test (|pitch| > {config.fallen_pitch_deg:.0f} deg)")
                return GetUpReport(False, tuple(attempts), reason, tracker=tracker)
            started = io.now_s()
            fallen_s = tracker.since_s
            lying = tracker.estimate.lying
            report = AttemptReport(k, started, fallen_s, lying)
            problems = health_problems(io.health(), config.health)
            if problems:
                attempts.append(replace(report, health=problems, ended_s=io.now_s(),
                                        why="refused: " + "; ".join(problems)))
                return give_up(f"health check failed before attempt {k}: {'; '.join(problems)}")
            held = io.hold()
            if held:
                log.warning("get-up attempt %d: cannot hold the lying posture (%s); reading it limp", k, held)
            held_s = io.now_s()
            c0 = cpu_clock()
            joints = io.read_joints()
            true_posture = truth.true_posture() if truth is not None else None
            estimate = estimator.estimate(joints, tracker.estimate.up_torso, truth=true_posture)
            c1 = cpu_clock()
            missing = [j for j in estimator.robot.joint_names if j not in joints]
            if missing:
                io.spent(c1 - c0)
                attempts.append(replace(report, estimate_cpu_s=c1 - c0, ended_s=io.now_s(),
                                        why=f"no angle from the servo(s) of {', '.join(missing)}"))
                return give_up(attempts[-1].why)
            try:
                planned = planner.plan(estimate, k)
            except Exception as e:  # noqa: BLE001 - an invalid estimate or a planner error ends this try, not the loop
                planned = PlannedGetUp(None, False, f"{type(e).__name__}: {e}")
            c2 = cpu_clock()
            io.spent(c2 - c0)
            report = replace(report, estimate=estimate, estimate_cpu_s=c1 - c0, plan_cpu_s=c2 - c1,
                             start_repair=planned.start_repair, proven=planned.proven, motion=planned.motion)
            if planned.start_repair is not None and planned.start_repair.changed:
                log.info("get-up attempt %d: %s", k, planned.start_repair.describe())
            if planned.trajectory is None or not (planned.proven or config.execute_unproven):
                attempts.append(replace(report, ended_s=io.now_s(), why=f"no proven get-up: {planned.reason}"))
                log.info("get-up attempt %d: no proven get-up: %s", k, planned.reason)
                continue  # the next try plans again (another seed) from where it lies
            tracker = _read_for(io, tracker, config, config.hold_before_s - (io.now_s() - held_s))  # the thinking held it too
            run = io.execute(planned.trajectory)
            report = replace(report, first_command_s=run.first_command_s, executed=run.completed)
            if run.interrupted:
                attempts.append(replace(report, ended_s=io.now_s(), why="interrupted by the operator"))
                return give_up("interrupted by the operator", interrupted=True)
            seen = confirm_standing(io, tracker, config)
            tracker, standing, why = seen.tracker, seen.standing, seen.why
            if not run.completed:
                why = f"the execution stopped: {run.reason}" + (f"; {why}" if why else "")
            attempts.append(replace(report, ended_s=io.now_s(), standing=standing, standing_s=seen.standing_s,
                                    why="" if standing else why))
            log.info("get-up attempt %d: %s", k, "standing" if standing else why)
            if standing:
                return GetUpReport(True, tuple(attempts), tracker=tracker)
            if seen.imu_lost:  # blind: it may be standing; the servos keep holding, no new try
                return give_up(f"{why}: servos left holding, no new try without the IMU", limp=False)
            again = [j for j in run.lagging_joints if j in lagged]
            if again:  # the same joint stopped two tries in a row: blocked, not bad luck
                return give_up(f"{', '.join(again)} stopped two get-ups in a row (blocked?): "
                               f"no new try, to protect the hardware; {why}")
            lagged = run.lagging_joints
            if config.limp_when_falling:
                io.go_limp()
            tracker = _read_for(io, tracker, config, config.fall.still_s)
        return give_up(f"not standing after {config.attempts} attempt(s): {attempts[-1].why}")
    except KeyboardInterrupt:  # outside the executor (which stops by its own policy): a safe stop
        if tracker.state is FallState.STANDING and not io.hold():
            why = "interrupted by the operator: standing, servos holding"
        else:
            io.go_limp()
            why = "interrupted by the operator: servos limp"
        log.warning("get-up: %s", why)
        return GetUpReport(False, tuple(attempts), why, interrupted=True, tracker=tracker)
