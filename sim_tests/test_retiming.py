"""Retiming (robot_rise/authoring/retiming.py): one retiming gives both timings the library author
tries, the fastest shorter than the one before the coordinate descent (whose pass/fail plays stop
at the first player that fails), and both stand on every player."""

from __future__ import annotations

import pytest
import logging

from robot_rise.authoring import motion_specs, robustness_players, settle
from robot_rise.authoring.keyframes import build_trajectory
from robot_rise.authoring.retiming import RETIME_SAME_FALL_LIMIT, retime, speed_prescale
from robot_rise.model import load_robot
from robot_rise.sim.standing import judge


@pytest.mark.slow
def test_one_retiming_gives_the_fastest_and_the_unrefined_timing_as_two_retimings_do() -> None:
    robot = load_robot()
    spec = next(s for s in motion_specs(robot) if s.name == "prone_elbow_knees")
    start = settle(robot, spec.lying, spec.lying_joints, yaw_rad=spec.lying_yaw_rad)
    # written slower than the servos allow, so the retiming has spare time to take back
    slow = speed_prescale(robot, start, tuple(type(k)(round(2.5 * k.t_s, 3), k.joints) for k in spec.keyframes))
    players = robustness_players(robot)[:2]  # nominal and a corner: the descent's early stop has a second player to skip
    both = retime(robot, start, slow, players, ratio_target=0.88, max_iter=6, refine_steps=(0.9,))
    assert both.unrefined == retime(robot, start, slow, players, ratio_target=0.88, max_iter=6, refine_steps=()).fastest
    assert both.fastest[-1].t_s < both.unrefined[-1].t_s < slow[-1].t_s
    for timing in (both.fastest, both.unrefined):
        for player in players:
            v = judge(player.play(build_trajectory(robot, start, timing)))
            assert v.standing and not v.self_collision, v.summary()


def test_a_motion_that_slowing_does_not_help_stops_being_slowed(caplog) -> None:
    # the prone get-up's lying posture held: within the torque target, never rises, falls the same
    # way however slowly it is played
    robot = load_robot()
    spec = next(s for s in motion_specs(robot) if s.name == "prone_elbow_knees")
    start = settle(robot, spec.lying, spec.lying_joints, yaw_rad=spec.lying_yaw_rad)
    lying = tuple(type(k)(k.t_s, dict(spec.lying_joints)) for k in spec.keyframes[:2])
    player = robustness_players(robot)[:1]
    with caplog.at_level(logging.WARNING, logger="robot_rise.authoring.retiming"):
        got = retime(robot, start, lying, player, max_iter=60, refine_steps=())
    first = speed_prescale(robot, start, lying)[-1].t_s
    # eight slowings of x1.1 and the ninth play: at most 1.1 ** 8 = 2.14 x (the 59 slowings max_iter allows: 278 x)
    assert got.fastest == got.unrefined
    assert first < got.fastest[-1].t_s <= 1.1 ** RETIME_SAME_FALL_LIMIT * first + 0.01
    assert "falls the same way" in caplog.text and f"after {RETIME_SAME_FALL_LIMIT} slowings in a row" in caplog.text
