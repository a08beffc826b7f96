"""A failed motion cut short before it goes over the torque bound (robot_rise/filter/stop.py), as a
rise after a failed attempt replays it: it stops before the replay first goes over, its last goals
are where the joints were, it stays under the bound, and the robot comes to rest."""

from __future__ import annotations

import numpy as np

from robot_rise.filter import STOP_BEFORE_S, STOP_RAMP_S, command_limits_for, stopped_before_torque_bound
from robot_rise.library import load_library
from robot_rise.sim.player import Player


def test_a_motion_over_a_low_bound_is_stopped_before_it_and_holds_where_the_joints_were(robot) -> None:
    motion = load_library().get("prone_elbow_knees").trajectory
    player = Player(robot, "flat")
    rec = player.play(motion, hold_s=0.5)
    limit = 0.6  # the motion peaks at ~0.8: over this one, somewhere after its first STOP_BEFORE_S
    first_over = float(rec.t[np.flatnonzero(rec.envelope_ratio.max(axis=1) > limit)[0]])
    assert first_over > 2 * STOP_BEFORE_S
    stopped = stopped_before_torque_bound(motion, rec, limit, command_limits_for(robot))
    assert stopped is not None and stopped.start == motion.start
    cut = first_over - STOP_BEFORE_S
    assert np.all(stopped.t[:-1] < cut) and stopped.duration_s >= cut + STOP_RAMP_S - 1e-9
    where = np.array([np.interp(cut, rec.t, rec.q[:, j]) for j in range(rec.q.shape[1])])
    assert np.allclose(stopped.q[-1], np.clip(where, robot.joint_lower, robot.joint_upper), atol=0.05)
    again = player.play(stopped, hold_s=2.0)
    assert again.envelope_ratio.max() <= limit + 0.05  # the servos stop pushing where they were
    assert np.max(np.abs(again.qd[-1])) < 0.5  # at rest: a posture to rise again from
    assert stopped_before_torque_bound(motion, rec, 2.0, command_limits_for(robot)) is None  # never over: nothing to stop
