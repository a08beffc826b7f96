"""The shipped motion library works as shipped: every motion starts inside its joint limits and
carries a proof that ``execution_permit`` allows (no replay here: ``robot-rise library prove``
writes the proofs, ``test_library`` replays the motions)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from robot_rise.proof import Proof, execution_permit
from robot_rise.library import default_library_dir, load_library
from robot_rise.model import load_robot
from robot_rise.posture import read_posture

ROBOT = load_robot()
LIBRARY = load_library()
ROWS = {row["name"]: row for row in json.loads((default_library_dir() / "index.json").read_text())["motions"]}


def _inside(q: np.ndarray) -> bool:
    return bool(np.all(q >= ROBOT.joint_lower) and np.all(q <= ROBOT.joint_upper))


@pytest.mark.parametrize("name", LIBRARY.names())
def test_a_shipped_motion_starts_and_stays_inside_its_joint_limits(name: str) -> None:
    m = LIBRARY.get(name)
    start_file = read_posture(default_library_dir() / ROWS[name]["start"])  # as written, not clamped on reading
    assert _inside(m.trajectory.start.joint_vector(ROBOT.joint_names)), "trajectory's start"
    assert _inside(start_file.joint_vector(ROBOT.joint_names)), "start file"
    assert m.trajectory.joint_names == ROBOT.joint_names
    assert all(_inside(row) for row in m.trajectory.q), "rows"


@pytest.mark.parametrize("name", LIBRARY.names())
def test_a_shipped_motion_carries_a_proof_on_flat_ground_that_permits_execution(name: str) -> None:
    report = LIBRARY.get(name).trajectory.report
    proof = Proof.from_dict(report, where=name)
    assert proof.proven and not proof.problems
    assert proof.robot == ROBOT.name and proof.scene == "flat"
    assert proof.peak_torque_ratio <= proof.envelope_limit
    permit = execution_permit(report, ROBOT)
    assert permit.allowed, f"{permit.reason}: re-prove with robot-rise library prove"
