"""A failed motion cut short before it goes over the torque bound: its goals up to shortly before,
then ramped to where the joints are, so that the servos stop pushing there."""

from __future__ import annotations

import numpy as np

from robot_rise.filter.command_limits import CommandLimits, conform
from robot_rise.sim.player import Recording
from robot_rise.trajectory import Trajectory

__all__ = ["STOP_BEFORE_S", "STOP_RAMP_S", "stopped_before_torque_bound"]

# the cut comes this long before the replay first goes over the bound: the servo's torque rises
# over a few of the recording's 100 Hz samples, not in one [s]
STOP_BEFORE_S = 0.1
# the goals then move to where the joints are in this long: a step of a saturated servo's tracking
# error (up to ~0.5 rad) at once would be a torque spike of its own [s]
STOP_RAMP_S = 0.1


def stopped_before_torque_bound(trajectory: Trajectory, recording: Recording, limit: float, limits: CommandLimits, *,
                                stop_before_s: float = STOP_BEFORE_S, ramp_s: float = STOP_RAMP_S) -> Trajectory | None:
    """``trajectory`` stopped ``stop_before_s`` before its replay ``recording`` first goes over
    ``limit`` (torque / envelope): its goals up to then (the last one interpolated at the cut, or
    its final goals when the cut falls in the hold after it), then a row ``ramp_s`` later with the
    joints where the replay had them at the cut, conformed to ``limits``. Its report is empty.

    Returns None when the replay never goes over ``limit``, or already within ``stop_before_s``.
    A rise after a failed attempt needs this: any replay of the whole failed attempt goes over the
    bound again, so no combined proof could hold.
    """
    over = np.flatnonzero(recording.envelope_ratio.max(axis=1) > limit)
    if over.size == 0:
        return None
    t_stop = float(recording.t[over[0]]) - stop_before_s
    if t_stop <= 0.0:
        return None
    keep = trajectory.t < t_stop
    at_cut = trajectory.sample(np.array([t_stop]))[0]
    cols = [recording.joint_names.index(j) for j in trajectory.joint_names]  # the recording is in the robot's joint order
    where = np.array([np.interp(t_stop, recording.t, recording.q[:, c]) for c in cols])
    stopped = Trajectory(trajectory.robot, trajectory.joint_names, np.concatenate([trajectory.t[keep], [t_stop, t_stop + ramp_s]]),
                         np.vstack([trajectory.q[keep], at_cut, where]), trajectory.start, {}, None)
    return conform(stopped, limits)
