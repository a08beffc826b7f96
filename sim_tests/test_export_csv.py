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


def test_ticks_per_servo_id_at_the_executors_rate_are_what_the_servo_map_makes_of_the_targets(tmp_path, capsys):
    """Issue 42: the trajectory as the robot's servos see it (one column per servo ID, ticks)."""
    from drivers import load_servo_map

    path, *_ = _trajectory(tmp_path)
    out = tmp_path / "ticks.csv"
    assert main(["export-csv", str(path), "--units", "ticks", "--rate", "100", "--out", str(out)]) == 0
    rows = list(csv.reader(out.open()))
    robot = load_robot()
    servo_map = load_servo_map(robot.directory / "servos.toml")
    assert rows[0] == ["t", *(str(i) for i in servo_map.ids)]
    assert len(rows) - 1 == 126  # 1.25 s at 100 Hz, both ends
    t = np.array([float(r[0]) for r in rows[1:]])
    assert np.allclose(np.diff(t), 0.01)
    from robot_rise.trajectory import read_trajectory

    tr = read_trajectory(path)
    q = tr.sample(np.array([0.5]))[0]
    expected = servo_map.to_ticks(q[[tr.joint_names.index(j) for j in servo_map.joint_names]])
    assert [int(x) for x in rows[1 + 50][1:]] == [int(x) for x in expected]
    assert "126 rows at 100 Hz x 20 servos [ticks]" in capsys.readouterr().out
