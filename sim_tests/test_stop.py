"""A failed motion cut short before it goes over the torque bound (robot_rise/filter/stop.py), as a
rise after a failed attempt replays it: its goals as they were up to the cut, then where the
joints were; the replay stays under the bound and the robot comes to rest."""

from __future__ import annotations

import numpy as np
import pytest

from robot_rise.filter import STOP_BEFORE_S, STOP_RAMP_S, command_limits_for, stopped_before_torque_bound
from robot_rise.library import load_library
from robot_rise.sim.player import Player
from robot_rise.trajectory import Trajectory


@pytest.mark.parametrize("every", [1, 50], ids=["every row", "sparse rows"])
def test_a_motion_over_a_low_bound_is_stopped_before_it_and_holds_where_the_joints_were(robot, every: int) -> None:
    full = load_library().get("prone_elbow_knees").trajectory
    rows = np.unique(np.append(np.arange(0, len(full.t), every), len(full.t) - 1))
    motion = Trajectory(full.robot, full.joint_names, full.t[rows], full.q[rows], full.start, {}, None)
    player = Player(robot, "flat")
    rec = player.play(motion, hold_s=0.5)
    limit = 0.6  # the motion peaks at ~0.8: over this one, somewhere after its first STOP_BEFORE_S
    first_over = float(rec.t[np.flatnonzero(rec.envelope_ratio.max(axis=1) > limit)[0]])
    assert first_over > 2 * STOP_BEFORE_S
    stopped = stopped_before_torque_bound(motion, rec, limit, command_limits_for(robot))
    assert stopped is not None and stopped.start == motion.start and stopped.report == {}
    cut = first_over - STOP_BEFORE_S
    kept = motion.t < cut
    # the goals as they were up to the cut (the executor's limits keep them off the joint limits by a hair)
    assert np.allclose(stopped.q[: kept.sum()], motion.q[kept], atol=0.02) and np.allclose(stopped.t[: kept.sum()], motion.t[kept])
    at_cut = np.array([np.interp(cut, motion.t, motion.q[:, j]) for j in range(motion.q.shape[1])])
    assert np.allclose(stopped.q[kept.sum()], at_cut, atol=0.02) and stopped.t[kept.sum()] == pytest.approx(cut)
    where = np.array([np.interp(cut, rec.t, rec.q[:, j]) for j in range(rec.q.shape[1])])
    assert np.allclose(stopped.q[-1], where, atol=0.02) and stopped.duration_s >= cut + STOP_RAMP_S - 1e-9
    again = player.play(stopped, hold_s=2.0)
    assert again.peak_envelope_ratio <= limit  # the servos stop pushing where they were
    assert np.max(np.abs(again.qd[-1])) < 0.5  # at rest: a posture to rise again from


def test_nothing_to_stop_when_the_bound_is_never_reached_or_already_at_the_start(robot) -> None:
    motion = load_library().get("prone_elbow_knees").trajectory
    rec = Player(robot, "flat").play(motion, hold_s=0.5)
    assert stopped_before_torque_bound(motion, rec, 2.0, command_limits_for(robot)) is None
    assert stopped_before_torque_bound(motion, rec, 0.0, command_limits_for(robot)) is None
