"""robot-rise export-csv: a trajectory file's rows as CSV, end to end through the CLI."""

from __future__ import annotations

import csv

import numpy as np

from robot_rise.cli import main
from robot_rise.model import load_robot
from robot_rise.posture import stand_posture
from robot_rise.trajectory import Trajectory, write_trajectory


def _trajectory(tmp_path):
    robot = load_robot()
    start = stand_posture(robot)
    q0 = start.joint_vector(robot.joint_names)
    t = np.array([0.0, 0.5, 1.25])
    q = np.stack([q0, q0 + 0.1, q0 - 0.2])
    path = tmp_path / "t.json"
    write_trajectory(path, Trajectory(robot.name, robot.joint_names, t, q, start, {}))
    return path, robot, t, q


def test_that_export_csv_writes_a_header_and_one_row_per_sample_in_radians(tmp_path, capsys):
    path, robot, t, q = _trajectory(tmp_path)
    out = tmp_path / "t.csv"
    assert main(["export-csv", str(path), "--out", str(out)]) == 0
    rows = list(csv.reader(out.open()))
    assert rows[0] == ["t", *robot.joint_names]
    got = np.array([[float(x) for x in r] for r in rows[1:]])
    np.testing.assert_allclose(got[:, 0], t, atol=1e-6)
    np.testing.assert_allclose(got[:, 1:], q, atol=1e-6)
    assert "3 rows" in capsys.readouterr().out


def test_that_export_csv_defaults_to_the_trajectory_name_and_refuses_a_missing_file(tmp_path, capsys):
    path, *_ = _trajectory(tmp_path)
    assert main(["export-csv", str(path)]) == 0
    assert (tmp_path / "t.csv").exists()
    assert main(["export-csv", str(tmp_path / "nope.json")]) == 2
    err = capsys.readouterr().err
    assert "no such trajectory file" in err and "Traceback" not in err
    assert not (tmp_path / "nope.csv").exists()
