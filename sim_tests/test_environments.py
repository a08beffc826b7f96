"""Paper 000 section 5.2 environments: each rises, or the result says which constraint stopped it."""

from __future__ import annotations

import re

import pytest

from robot_rise.rise import rise
from robot_rise.sampling import sample_lying_postures

# A failure reason must name a constraint: a collision class, the judge, the torque envelope or the planner's budget.
CONSTRAINT = re.compile(r"collision|not standing|envelope|budget|invalid|no path|self-collision")


def _rise_in(robot, scene: str):
    posture = sample_lying_postures(robot, "prone", 1, seed=2, scene=scene).postures[0]
    return rise(robot, posture, scene=scene, candidates=2, budget_s=15)


def test_rise_with_a_beam_under_the_face_is_proven(robot):
    result = _rise_in(robot, "beam")
    assert result.ok, result.reason
    assert result.trajectory.report["scene"] == "beam"


@pytest.mark.slow
@pytest.mark.parametrize("scene", ["low_bed", "table", "icy", "soft", "slope"])
def test_rise_in_each_environment_succeeds_or_names_the_constraint(robot, scene):
    result = _rise_in(robot, scene)
    if result.ok:
        assert result.trajectory.report["proven"] is True
    else:
        assert result.attempts, "no candidate was tried"
        for attempt in result.attempts:
            assert CONSTRAINT.search(attempt.describe()), attempt.describe()
