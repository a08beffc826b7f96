"""A failed motion cut short before it goes over the torque bound, as the executor stops one: the
goals up to shortly before, then ramped to where the joints are."""

from __future__ import annotations

import numpy as np

from robot_rise.filter.command_limits import CommandLimits, conform
from robot_rise.sim.player import Recording
from robot_rise.trajectory import Trajectory

__all__ = ["STOP_BEFORE_S", "STOP_RAMP_S", "stopped_before_torque_bound"]

STOP_BEFORE_S = 0.1  # the goals are cut this long before the replay first goes over the bound [s]
STOP_RAMP_S = 0.1  # ... and then ramp in this long to where the joints were at the cut [s]


def stopped_before_torque_bound(trajectory: Trajectory, recording: Recording, limit: float, limits: CommandLimits, *,
                                stop_before_s: float = STOP_BEFORE_S, ramp_s: float = STOP_RAMP_S) -> Trajectory | None:
    """``trajectory`` stopped ``stop_before_s`` before its replay ``recording`` first goes over
    ``limit`` (torque / envelope): its rows before then, then one row ``ramp_s`` later holding the
    joints where the replay had them at the cut (the servos stop pushing), within ``limits``.

    Returns None when the replay never goes over ``limit``, or already within ``stop_before_s``.
    The combined proof of a rise after a failed attempt needs this: the whole failed attempt goes
    over the bound again in any replay of it.
    """
    over = np.flatnonzero(recording.envelope_ratio.max(axis=1) > limit)
    if over.size == 0:
        return None
    t_stop = float(recording.t[over[0]]) - stop_before_s
    keep = trajectory.t < t_stop
    if t_stop <= 0.0 or not keep.any():
        return None
    where = np.array([np.interp(t_stop, recording.t, recording.q[:, j]) for j in range(recording.q.shape[1])])
    stopped = Trajectory(trajectory.robot, trajectory.joint_names, np.append(trajectory.t[keep], t_stop + ramp_s),
                         np.vstack([trajectory.q[keep], where]), trajectory.start, trajectory.report, None)
    return conform(stopped, limits)
