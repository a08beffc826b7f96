"""Live operation on the robot: fall detection, where the body lies, the get-up loop and the guard.

Pure code on SI samples; it talks to hardware only through interfaces the CLI wires to
``drivers`` (it never imports ``drivers`` itself).

- :mod:`~robot_rise.live.fall`: standing / falling / fallen-and-still with the lying kind, from
  the IMU's gravity direction and gyro, in every direction.
- :mod:`~robot_rise.live.estimate`: the whole lying posture from the joint angles and the IMU's
  gravity direction (roll and pitch from gravity, position by settling the model).
- :mod:`~robot_rise.live.health`: the servos' health before a try, and the reasons not to move.
- :mod:`~robot_rise.live.io`: the :class:`RobotIO` interface, the robot as the loop sees it (the
  CLI wires it to ``drivers``).
- :mod:`~robot_rise.live.planners`: get-up planners from an estimated posture (ours: ``rise``,
  proven; the stock OP3's keyframes, for comparison).
- :mod:`~robot_rise.live.getup`: the get-up loop (estimate, plan and prove, execute, confirm
  standing, retry, give up limp).
- :mod:`~robot_rise.live.guard`: the guard (limp while falling, get up once fallen).

The push benchmark over the guard is ``robot_rise.bench.pushes`` (above the core).
"""

from robot_rise.live.estimate import (
    EstimateConfig,
    EstimateError,
    PostureEstimate,
    PostureEstimator,
    estimate_error,
    estimate_posture,
    root_quat_from_up,
    up_of_quat,
)
from robot_rise.live.fall import (
    LYING_KINDS,
    FallConfig,
    FallEstimate,
    FallState,
    FallTracker,
    LyingKind,
    TorsoAxes,
    detect,
    lying_kind,
    new_tracker,
    step,
)
from robot_rise.live.getup import (
    AttemptReport,
    Confirmation,
    GetUpConfig,
    GetUpReport,
    confirm_standing,
    get_up,
    watch,
)
from robot_rise.live.guard import GuardEvent, GuardEventKind, GuardState, guard, guard_step, stop_safely
from robot_rise.live.health import Health, HealthLimits, health_limits_for_supply, health_problems
from robot_rise.live.io import ExecutionResult, RobotIO, TruthSource
from robot_rise.live.planners import GetUpPlanner, KeyframePlanner, PlannedGetUp, RisePlanner

__all__ = [
    "LYING_KINDS",
    "LyingKind",
    "FallConfig",
    "FallEstimate",
    "FallState",
    "FallTracker",
    "TorsoAxes",
    "detect",
    "lying_kind",
    "new_tracker",
    "step",
    "EstimateConfig",
    "EstimateError",
    "PostureEstimate",
    "PostureEstimator",
    "estimate_error",
    "estimate_posture",
    "root_quat_from_up",
    "up_of_quat",
    "AttemptReport",
    "Confirmation",
    "ExecutionResult",
    "GetUpConfig",
    "GetUpPlanner",
    "GetUpReport",
    "GuardEvent",
    "GuardEventKind",
    "GuardState",
    "Health",
    "HealthLimits",
    "health_limits_for_supply",
    "KeyframePlanner",
    "PlannedGetUp",
    "RisePlanner",
    "RobotIO",
    "TruthSource",
    "confirm_standing",
    "get_up",
    "guard",
    "guard_step",
    "health_problems",
    "stop_safely",
    "watch",
]
