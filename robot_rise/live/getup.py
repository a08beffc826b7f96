"""The live get-up loop and the guard that runs it, as plain functions over small interfaces.

Nothing here talks to hardware: :class:`RobotIO` is the robot as the loop sees it (joint angles,
IMU samples, health, execute a trajectory, go limp, hold), and ``robot_rise.cli`` wires it to
``drivers`` (a real bus, or the emulated bus moved by the physics twin).

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

:func:`guard_step` / :func:`guard` watch the IMU at the cycle rate: FALLING goes limp at once (the
servos do not fight the impact), FALLEN runs :func:`get_up`. A FALLEN read while its own get-up
runs is not acted on: the loop is inside :func:`get_up` then, and only reads the IMU again to
confirm standing. Ctrl-C stops safely (lying: limp; standing: hold).

:func:`push_trials` is the benchmark the issue asks for: push the standing robot (a
:class:`Pusher`: the twin), let the guard do its work, report per push. The stock OP3's scheme
runs in the same loop for comparison: :class:`KeyframePlanner` (a front and a back keyframe
get-up, unproven) with ``GetUpConfig(limp_when_falling=False, fallen_pitch_deg=60,
execute_unproven=True)``.

Time: every time is on the IO's clock (``RobotIO.now_s``: the bus clock, simulated with the twin).
Thinking (estimate, plan, proof) takes no simulated time by itself; its CPU time (one core's worth,
``time.process_time``) is handed to ``RobotIO.spent``, which lets that much time pass on a
simulated clock (a real clock has passed it already), so latencies include it.
"""

from __future__ import annotations

import enum
import logging
import math
import random
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Protocol, runtime_checkable

import numpy as np

from robot_rise.errors import RobotRiseError
from robot_rise.filter.config import FilterConfig
from robot_rise.live.estimate import PostureEstimate, PostureEstimator
from robot_rise.library import MotionLibrary
from robot_rise.live.fall import FallConfig, FallState, FallTracker, ImuSampleLike, new_tracker, step
from robot_rise.model import Robot
from robot_rise.posture import Posture
from robot_rise.rise import RiseContext, rise
from robot_rise.trajectory import Trajectory

__all__ = [
    "Health",
    "HealthLimits",
    "health_limits_for_supply",
    "health_problems",
    "ExecutionResult",
    "RobotIO",
    "TruthSource",
    "PlannedGetUp",
    "GetUpPlanner",
    "RisePlanner",
    "KeyframePlanner",
    "GetUpConfig",
    "pitch_deg",
    "AttemptReport",
    "GetUpReport",
    "watch",
    "Confirmation",
    "confirm_standing",
    "get_up",
    "GuardEventKind",
    "GuardEvent",
    "GuardState",
    "guard_step",
    "guard",
    "stop_safely",
    "Pusher",
    "PushConfig",
    "PushOutcome",
    "push_trials",
    "summarize_pushes",
    "RISE_WITHIN_S",
]

log = logging.getLogger(__name__)

RISE_WITHIN_S = 20.0  # [s] RoboCup: a robot not up within 20 s of falling is declared incapable


# ---- health ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Health:
    """The servos' state before a try.

    Attributes:
        temperatures_c: servo temperature by joint [degC].
        voltages_v: servo input voltage by joint [V].
        hardware_errors: a description of the hardware error by joint (only joints with one).
        missing: joints whose servo did not answer.
    """

    temperatures_c: Mapping[str, float] = field(default_factory=dict)
    voltages_v: Mapping[str, float] = field(default_factory=dict)
    hardware_errors: Mapping[str, str] = field(default_factory=dict)
    missing: tuple[str, ...] = ()


@dataclass(frozen=True)
class HealthLimits:
    """When not to try (ours). A get-up is 5-10 s of hard work: it must start with headroom below
    the executor's own abort thresholds (``drivers.safety.SafetyLimits``: 70 degC, 10.0 V).

    Attributes:
        max_temperature_c: [degC] a hotter servo refuses the try: the XM430's windings gain a
            few kelvin in a get-up; 65 keeps the executor's 70 degC abort out of reach.
        min_voltage_v: [V] below it the supply is nearly flat (a 3S LiPo at 3.5 V a cell); the
            servos lose torque the proof counted on (its weakest variant: the supply -7.5 %, 11.1 V of 12).
        max_voltage_v: [V] above the servos' recommended range.
    """

    max_temperature_c: float = 65.0
    min_voltage_v: float = 10.5
    max_voltage_v: float = 14.5


def health_limits_for_supply(supply_v: float) -> HealthLimits:
    """:class:`HealthLimits` for servos on ``supply_v`` (the servo map's ``[bus]
    supply_voltage_v``): the 12 V figures scaled (a 4S LiPo's 14.8 V: 12.95-17.9 V)."""
    k = supply_v / 12.0
    return replace(HealthLimits(), min_voltage_v=HealthLimits.min_voltage_v * k, max_voltage_v=HealthLimits.max_voltage_v * k)


def health_problems(health: Health, limits: HealthLimits = HealthLimits()) -> tuple[str, ...]:
    """One line per reason not to move (empty: healthy)."""
    out = [f"servo of {j} did not answer" for j in health.missing]
    out += [f"{j}: hardware error ({why})" for j, why in health.hardware_errors.items()]
    out += [f"{j}: {t:.0f} degC, above {limits.max_temperature_c:.0f} degC"
            for j, t in health.temperatures_c.items() if not t <= limits.max_temperature_c]
    out += [f"{j}: {v:.1f} V, outside {limits.min_voltage_v:.1f}..{limits.max_voltage_v:.1f} V"
            for j, v in health.voltages_v.items() if not limits.min_voltage_v <= v <= limits.max_voltage_v]
    return tuple(out)


# ---- the robot as the loop sees it ------------------------------------------------------------


@dataclass(frozen=True)
class ExecutionResult:
    """How one trajectory ran.

    Attributes:
        completed: it ran to the end without a fault.
        first_command_s: IO clock time of the first goal sent [s] (None: nothing was sent).
        ended_s: IO clock time at the end [s].
        reason: why it stopped or was refused (empty when completed).
        interrupted: the operator stopped it (Ctrl-C).
        lagging_joints: joints whose servo it stopped for, off the proof's predicted position (a
            blocked shaft, or the body went elsewhere).
    """

    completed: bool
    first_command_s: float | None
    ended_s: float
    reason: str = ""
    interrupted: bool = False
    lagging_joints: tuple[str, ...] = ()


@runtime_checkable
class RobotIO(Protocol):
    """The robot as the get-up loop sees it (SI units; joint angles in the model's joint frame)."""

    def now_s(self) -> float:
        """The IO clock [s] (monotonic; simulated with the twin)."""
        ...

    def sleep(self, duration_s: float) -> None:
        """Let ``duration_s`` [s] pass (the loop's cycle)."""
        ...

    def spent(self, compute_s: float) -> None:
        """The loop thought for ``compute_s`` [s] of CPU: a simulated clock lets that much time
        pass (a real one already has)."""
        ...

    def read_joints(self) -> Mapping[str, float]:
        """Present joint angles by joint name [rad] (one sync read); missing servos left out."""
        ...

    def read_imu(self) -> ImuSampleLike:
        """One IMU sample (torso frame, SI; ``valid`` False when the read failed)."""
        ...

    def health(self) -> Health:
        """Temperatures, voltages, hardware errors of every servo."""
        ...

    def execute(self, trajectory: Trajectory) -> ExecutionResult:
        """Stream a proven trajectory under the executor's safety layer (holds at the end)."""
        ...

    def go_limp(self) -> None:
        """Torque off now (falling, lying, giving up); never raises (a failure is logged)."""
        ...

    def hold(self) -> str:
        """Torque on holding the present posture (no motion); returns why not ('' when holding),
        never raises."""
        ...


@runtime_checkable
class TruthSource(Protocol):
    """Where the body truly lies (the physics twin only): for the estimate's error."""

    def true_posture(self) -> Posture: ...


# ---- planning ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class PlannedGetUp:
    """A get-up for the present posture, or why there is none.

    Attributes:
        trajectory: servo targets from the estimated posture (None: none found).
        proven: the trajectory carries a proof (only proven trajectories are executed).
        reason: why not proven (empty when proven).
        motion: the library motion it ends in.
    """

    trajectory: Trajectory | None
    proven: bool
    reason: str = ""
    motion: str = ""


class GetUpPlanner(Protocol):
    """Plans and proves a get-up from an estimated lying posture."""

    def plan(self, estimate: PostureEstimate, attempt: int) -> PlannedGetUp: ...


class RisePlanner:
    """:func:`robot_rise.rise.rise` with a per-robot precomputed :class:`RiseContext`.

    The first proven candidate is returned (anytime in candidates: nearest library motion first;
    a proof includes the ensemble). ``retries`` is 0 by default: a failed get-up is retried on the
    robot, from where it really lies, not in simulation.

    Args:
        context: checker, library, frame index, K-means tree and the ensemble's players.
        budget_s: planning budget per candidate [s].
        candidates: library motions tried, nearest first.
        retries: rise's own in-simulation retries.
        filter_config: the dynamics filter (ensemble proof on by default).
        composed: compose the ensemble proof with the library motions' start proofs where it
            applies (``robot_rise.filter.composed``; precompute them: ``RiseContext.warm_start_proofs``).
    """

    def __init__(self, context: RiseContext, *, budget_s: float = 5.0, candidates: int = 3, retries: int = 0,
                 filter_config: FilterConfig = FilterConfig(), composed: bool = False) -> None:
        self.context = context
        self.composed = composed
        self.budget_s = budget_s
        self.candidates = candidates
        self.retries = retries
        self.filter_config = filter_config

    def plan(self, estimate: PostureEstimate, attempt: int) -> PlannedGetUp:
        ctx = self.context
        result = rise(ctx.robot, estimate.posture, scene=ctx.scene, seed=attempt, budget_s=self.budget_s,
                      candidates=self.candidates, context=ctx, retries=self.retries,
                      filter_config=self.filter_config, composed=self.composed)
        motion = str(result.trajectory.report.get("motion", "")) if result.trajectory is not None else ""
        return PlannedGetUp(result.trajectory if result.proven else None, result.proven, result.reason, motion)


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


# ---- one get-up --------------------------------------------------------------------------------


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


def _fallen_by_config(tracker: FallTracker, config: GetUpConfig) -> bool:
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
            if not _fallen_by_config(tracker, config):  # the stock OP3's pitch test does not see it
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
                             proven=planned.proven, motion=planned.motion)
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


# ---- the guard ---------------------------------------------------------------------------------


class GuardEventKind(enum.Enum):
    """What the guard did."""

    FALLING = "falling"  # went limp
    GETUP = "getup"  # a get-up ran (report attached)
    HOLDING = "holding"  # standing (at the start, or stood up by hand after a give-up): servos hold it
    IMU_LOST = "imu lost"  # the IMU stopped answering: limp


@dataclass(frozen=True)
class GuardEvent:
    """One thing the guard did, at IO time ``t_s`` [s]."""

    t_s: float
    kind: GuardEventKind
    detail: str = ""
    report: GetUpReport | None = None


@dataclass(frozen=True)
class GuardState:
    """The guard's memory between cycles.

    Attributes:
        tracker: the fall detector.
        limp: torque is off, or not known to be on (the guard holds a standing robot).
        gave_up: the last get-up gave up: no new try until the robot stands again (by hand).
        bad_imu: unusable IMU samples in a row.
    """

    tracker: FallTracker
    limp: bool = False
    gave_up: bool = False
    bad_imu: int = 0


def guard_step(io: RobotIO, planner: GetUpPlanner, estimator: PostureEstimator, state: GuardState, *,
               config: GetUpConfig = GetUpConfig(), truth: TruthSource | None = None,
               cpu_clock: Callable[[], float] = time.process_time) -> tuple[GuardState, tuple[GuardEvent, ...]]:
    """One guard cycle: read the IMU, act on the detector's state (no sleep; the caller paces)."""
    tracker = step(state.tracker, io.read_imu())
    bad = state.bad_imu + 1 if tracker is state.tracker else 0
    state = replace(state, tracker=tracker, bad_imu=bad)
    now = tracker.estimate.t_s if math.isfinite(tracker.estimate.t_s) else io.now_s()
    if bad == config.imu_lost_after:
        io.go_limp()
        return replace(state, limp=True), (GuardEvent(io.now_s(), GuardEventKind.IMU_LOST,
                                                      f"{bad} IMU reads in a row failed: limp"),)
    if tracker.state is FallState.FALLING and not state.limp and config.limp_when_falling:
        io.go_limp()
        e = tracker.estimate
        return replace(state, limp=True), (GuardEvent(now, GuardEventKind.FALLING,
                                                      f"tilt {math.degrees(e.tilt_rad):.0f} deg at "
                                                      f"{e.tilt_rate_rad_s:.1f} rad/s: limp"),)
    if _fallen_by_config(tracker, config) and not state.gave_up:
        if not state.limp and config.limp_when_falling:
            io.go_limp()  # lying: no servo holds a pose it was not asked to
        report = get_up(io, planner, estimator, config=config, tracker=tracker, truth=truth, cpu_clock=cpu_clock)
        state = GuardState(report.tracker, limp=not report.standing, gave_up=not report.standing)
        detail = "standing" if report.standing else report.reason
        return state, (GuardEvent(io.now_s(), GuardEventKind.GETUP, detail, report),)
    if tracker.state is FallState.STANDING and state.limp:
        why = io.hold()  # standing at the start, or stood up by hand after a give-up: hold it, armed again
        if why:
            return state, ()
        return replace(state, limp=False, gave_up=False), (GuardEvent(now, GuardEventKind.HOLDING, "standing: servos hold it"),)
    return state, ()


def stop_safely(io: RobotIO, state: GuardState) -> str:
    """Ctrl-C: a robot on its feet keeps holding (limp, it would fall); otherwise limp."""
    if state.tracker.state is FallState.STANDING and not state.limp:
        why = io.hold()
        if not why:
            return "stopped: standing, servos holding the present posture"
        io.go_limp()
        return f"stopped: servos limp (could not hold: {why})"
    io.go_limp()
    return "stopped: servos limp"


def guard(io: RobotIO, planner: GetUpPlanner, estimator: PostureEstimator, *,
          config: GetUpConfig = GetUpConfig(), stop: Callable[[], bool] = lambda: False,
          on_event: Callable[[GuardEvent], None] | None = None, truth: TruthSource | None = None,
          cpu_clock: Callable[[], float] = time.process_time) -> GuardState:
    """Watch the IMU until ``stop()`` (or Ctrl-C, or a get-up the operator interrupted); then
    :func:`stop_safely`. Every event goes to ``on_event``. A robot standing at the start is held
    (torque on at its present posture)."""
    state = GuardState(new_tracker(config.fall), limp=True)
    try:
        while not stop():
            state, events = guard_step(io, planner, estimator, state, config=config, truth=truth, cpu_clock=cpu_clock)
            for event in events:
                if on_event is not None:
                    on_event(event)
            if any(e.report is not None and e.report.interrupted for e in events):
                break
            io.sleep(config.cycle_s)
    except KeyboardInterrupt:
        log.warning("guard: interrupted")
    message = stop_safely(io, state)
    log.info("guard: %s", message)
    return state


# ---- the push benchmark ------------------------------------------------------------------------


class Pusher(Protocol):
    """Pushes the robot (the physics twin) and puts it back on its feet."""

    def push(self, force_heading_n: tuple[float, float], duration_s: float) -> None:
        """Push the torso horizontally: ``force_heading_n`` [N] in the robot's heading frame
        (x forward, y to its left), for ``duration_s`` [s] from now."""
        ...

    def reset_standing(self) -> None:
        """Put the robot back on its feet, at rest (servos still to be engaged)."""
        ...


@dataclass(frozen=True)
class PushConfig:
    """The push benchmark (ours).

    Attributes:
        force_n: [N] (low, high) of the uniform push strength, for ``duration_s`` at the torso: the
            twin's OP3 withstands 15 N (0.1 s) from the front and 20 N from the side
            (fall.FallConfig), and a 30 N push topples it every way; up to 60 N tests hard falls.
        duration_s: [s] how long each push lasts.
        stand_s: [s] standing (the detector's STANDING) this long before each push.
        withstood_s: [s] still standing this long after the push: it did not topple.
        episode_s: [s] longest episode (push to the end of the guard's get-up).
    """

    force_n: tuple[float, float] = (20.0, 60.0)
    duration_s: float = 0.1
    stand_s: float = 1.0
    withstood_s: float = 3.0
    episode_s: float = 90.0


@dataclass(frozen=True)
class PushOutcome:
    """One push and what the guard made of it (times from the IO clock).

    Attributes:
        push: 0-based index.
        heading_deg: push direction in the robot's heading frame [deg] (0 forward, 90 to its left).
        force_n: push strength [N] (for ``PushConfig.duration_s``).
        toppled: the robot fell (the detector read fallen-and-still).
        max_tilt_deg: the largest tilt before it lay still (or in the episode) [deg].
        lying: the lying kind once fallen-and-still (None: did not topple).
        first_command_after_s: from fallen-and-still (the first time, after the push) to the
            first rising command of any attempt [s].
        standing: standing again at the end.
        standing_after_s: from the push to standing confirmed [s].
        attempts: get-up attempts made.
        reasons: per attempt, why it did not stand (empty strings for the one that did).
        orientation_error_deg: per attempt, the estimate's orientation error against the truth [deg].
        plan_cpu_s: per attempt, CPU time of estimate + plan + proof [s].
    """

    push: int
    heading_deg: float
    force_n: float
    toppled: bool
    max_tilt_deg: float
    lying: str | None
    first_command_after_s: float | None
    standing: bool
    standing_after_s: float | None
    attempts: int
    reasons: tuple[str, ...] = ()
    orientation_error_deg: tuple[float, ...] = ()
    plan_cpu_s: tuple[float, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        return {
            "push": self.push, "heading_deg": self.heading_deg, "force_n": self.force_n, "toppled": self.toppled,
            "max_tilt_deg": self.max_tilt_deg, "lying": self.lying, "first_command_after_s": self.first_command_after_s,
            "standing": self.standing, "standing_after_s": self.standing_after_s, "attempts": self.attempts,
            "reasons": list(self.reasons), "orientation_error_deg": list(self.orientation_error_deg),
            "plan_cpu_s": list(self.plan_cpu_s),
        }


def _stand_ready(io: RobotIO, pusher: Pusher, state: GuardState, config: GetUpConfig, stand_s: float) -> GuardState:
    """Standing, servos holding, detector STANDING for ``stand_s``; reset by the pusher if not."""
    for _ in range(3):
        if state.tracker.state is not FallState.STANDING or state.limp or state.gave_up:
            pusher.reset_standing()
            why = io.hold()
            if why:
                raise RobotRiseError(f"the servos do not hold the robot put back on its feet: {why}")
            state = GuardState(new_tracker(config.fall))
        t0 = io.now_s()
        while io.now_s() - t0 < stand_s + config.fall.upright_s + 1.0:
            state = replace(state, tracker=step(state.tracker, io.read_imu()))
            if state.tracker.state is FallState.STANDING and io.now_s() - state.tracker.since_s >= stand_s:
                return state
            io.sleep(config.cycle_s)
        state = replace(state, limp=True)  # not standing: reset again
    raise RobotRiseError("the robot does not stand after being put back on its feet three times")


def push_trials(io: RobotIO, planner: GetUpPlanner, estimator: PostureEstimator, pusher: Pusher, *, n: int,
                seed: int = 0, config: GetUpConfig = GetUpConfig(), push: PushConfig = PushConfig(),
                truth: TruthSource | None = None, on_push: Callable[[PushOutcome], None] | None = None,
                cpu_clock: Callable[[], float] = time.process_time) -> list[PushOutcome]:
    """Push the standing robot ``n`` times (random direction and strength, seeded) and let the
    guard handle each: go limp while falling, get up once fallen and still.

    Before each push the robot stands (put back on its feet by the pusher when the previous
    episode did not end standing). An episode ends when the guard's get-up ends (standing or
    given up), when the robot still stands ``push.withstood_s`` after the push, or after
    ``push.episode_s``.
    """
    rng = random.Random(seed)
    out: list[PushOutcome] = []
    state = GuardState(new_tracker(config.fall), limp=True)
    for i in range(n):
        heading = rng.uniform(-180.0, 180.0)
        force = rng.uniform(*push.force_n)
        state = _stand_ready(io, pusher, state, config, push.stand_s)
        t_push = io.now_s()
        h = math.radians(heading)
        pusher.push((force * math.cos(h), force * math.sin(h)), push.duration_s)
        max_tilt = 0.0
        lying: str | None = None
        report: GetUpReport | None = None
        left_standing = False
        while io.now_s() - t_push < push.episode_s:
            if state.tracker.state is FallState.FALLEN and lying is None:
                lying = state.tracker.estimate.lying
            state, events = guard_step(io, planner, estimator, state, config=config, truth=truth, cpu_clock=cpu_clock)
            report = next((ev.report for ev in events if ev.report is not None), None)
            if report is not None:
                break
            e = state.tracker.estimate
            if lying is None and math.isfinite(e.tilt_rad):
                max_tilt = max(max_tilt, math.degrees(e.tilt_rad))
            left_standing = left_standing or state.tracker.state is not FallState.STANDING
            if not left_standing and io.now_s() - t_push >= push.withstood_s:
                break
            io.sleep(config.cycle_s)
        toppled = (report is not None and bool(report.attempts)) or lying is not None
        first = report.attempts[0] if report is not None and report.attempts else None
        if first is not None and lying is None:
            lying = first.lying
        commanded = next((a.first_command_s for a in (report.attempts if report else ()) if a.first_command_s is not None), None)
        first_command_after = (commanded - first.fallen_s) if commanded is not None and first is not None and first.fallen_s is not None else None
        standing = report.standing if report is not None else state.tracker.state is FallState.STANDING
        standing_s = report.standing_s if report is not None else None
        outcome = PushOutcome(
            push=i, heading_deg=heading, force_n=force, toppled=toppled, max_tilt_deg=max_tilt, lying=lying,
            first_command_after_s=first_command_after,
            standing=standing, standing_after_s=(standing_s - t_push) if standing_s is not None else None,
            attempts=len(report.attempts) if report is not None else 0,
            reasons=tuple(a.why for a in report.attempts) if report is not None else (),
            orientation_error_deg=tuple(a.estimate.error.orientation_deg for a in (report.attempts if report else ())
                                        if a.estimate is not None and a.estimate.error is not None),
            plan_cpu_s=tuple(a.estimate_cpu_s + a.plan_cpu_s for a in (report.attempts if report else ())
                             if a.estimate is not None),
        )
        out.append(outcome)
        if on_push is not None:
            on_push(outcome)
    return out


def _percentile(values: Sequence[float], q: float) -> float | None:
    return float(np.percentile(np.asarray(values, dtype=float), q)) if len(values) else None


def _share(hits: int, total: int) -> float | None:
    return hits / total if total else None


def summarize_pushes(outcomes: Sequence[PushOutcome], *, within_s: float = RISE_WITHIN_S,
                     max_attempts: int = 3) -> dict[str, Any]:
    """The benchmark's figures over the pushes that toppled the robot, overall, for side falls
    (lying on a side once still) and for side pushes (60..120 deg either way), and by lying kind.

    Keys per group: ``n``, ``standing`` (share standing at the end), ``within_s`` (share standing
    within ``within_s`` of the push), ``within_attempts`` (share standing within
    ``max_attempts`` attempts), ``first_command_p50_s`` / ``p95_s`` / ``max_s``, ``standing_after_p50_s``
    / ``p95_s``, ``orientation_error_p95_deg``, ``orientation_within_3deg`` (share of estimates).
    """
    def group(rows: Sequence[PushOutcome]) -> dict[str, Any]:
        lat = [r.first_command_after_s for r in rows if r.first_command_after_s is not None]
        up = [r.standing_after_s for r in rows if r.standing_after_s is not None]
        errs = [e for r in rows for e in r.orientation_error_deg]
        return {
            "n": len(rows),
            "standing": _share(sum(r.standing for r in rows), len(rows)),
            "within_s": _share(sum(r.standing and r.standing_after_s is not None and r.standing_after_s <= within_s
                                   for r in rows), len(rows)),
            "within_attempts": _share(sum(r.standing and r.attempts <= max_attempts for r in rows), len(rows)),
            "first_command_p50_s": _percentile(lat, 50), "first_command_p95_s": _percentile(lat, 95),
            "first_command_max_s": max(lat) if lat else None,
            "standing_after_p50_s": _percentile(up, 50), "standing_after_p95_s": _percentile(up, 95),
            "orientation_error_p95_deg": _percentile(errs, 95),
            "orientation_within_3deg": _share(sum(e <= 3.0 for e in errs), len(errs)),
        }

    toppled = [r for r in outcomes if r.toppled]
    side_push = [r for r in toppled if 60.0 <= abs(r.heading_deg) <= 120.0]
    return {
        "pushes": len(outcomes),
        "toppled": len(toppled),
        "within_limit_s": within_s,
        "all": group(toppled),
        "side_falls": group([r for r in toppled if r.lying in ("left", "right")]),
        "side_pushes": group(side_push),
        "by_lying": {kind: group([r for r in toppled if r.lying == kind]) for kind in ("supine", "prone", "left", "right")},
    }
