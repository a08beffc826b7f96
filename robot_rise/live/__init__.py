"""Live operation on the robot: fall detection (and, later, posture estimation and the guard loop).

Pure code on SI samples; it talks to hardware only through interfaces the CLI wires to
``drivers`` (it never imports ``drivers`` itself).

- :mod:`~robot_rise.live.fall`: standing / falling / fallen-and-still with the lying kind, from
  the IMU's gravity direction and gyro, in every direction.
"""

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
]
