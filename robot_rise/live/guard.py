"""The guard: watch the IMU at the cycle rate, go limp while falling, get up once fallen.

:func:`guard_step` / :func:`guard`: FALLING goes limp at once (the servos do not fight the impact),
FALLEN runs :func:`~robot_rise.live.getup.get_up`. A FALLEN read while its own get-up runs is not
acted on: the loop is inside ``get_up`` then, and only reads the IMU again to confirm standing.
Ctrl-C stops safely (lying: limp; standing: hold).
"""

from __future__ import annotations

import enum
import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

from robot_rise.live.estimate import PostureEstimator
from robot_rise.live.fall import FallState, FallTracker, new_tracker, step
from robot_rise.live.getup import GetUpConfig, GetUpReport, fallen_by_config, get_up
from robot_rise.live.io import RobotIO, TruthSource
from robot_rise.live.planners import GetUpPlanner

__all__ = ["GuardEventKind", "GuardEvent", "GuardState", "guard_step", "guard", "stop_safely"]

log = logging.getLogger(__name__)


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
    if fallen_by_config(tracker, config) and not state.gave_up:
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
