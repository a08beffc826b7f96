"""A user's own get-up read from keyframes (robot_rise.keyframe_import) and added to a library
(``robot-rise library add``, robot_rise.authoring.user_motion), proven like the library's own."""

from __future__ import annotations

import csv
import json
import shutil

import numpy as np
import pytest

from robot_rise.cli import main
from robot_rise.errors import FormatError
from robot_rise.keyframe_export import KEYFRAMES_FORMAT, write_keyframes
from robot_rise.keyframe_import import KEYFRAMES_CSV_FORMAT, read_keyframes, read_keyframes_csv, read_mujoco_keyframes
from robot_rise.library import load_library, robot_library_dir
from robot_rise.model import load_robot
from robot_rise.proof import execution_permit
from robot_rise.seal import seal_problem
from robot_rise.trajectory import write_csv

MOTION = "prone_knees_first"


@pytest.fixture(scope="module")
def robot():
    return load_robot(None)


@pytest.fixture(scope="module")
def shipped(robot):
    return load_library(robot_library_dir(robot)).get(MOTION)


def _write_rows(path, header, rows):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(rows)
    return path


def _small_csv(tmp_path, robot, *, header=None, times=(0.0, 0.5, 1.0), value=0.1):
    names = list(robot.joint_names)
    rows = [[t, *([value] * len(names))] for t in times]
    return _write_rows(tmp_path / "keys.csv", header or ["time_s", *names], rows)


def _one_line_error(call) -> str:
    with pytest.raises(FormatError) as e:
        call()
    text = str(e.value)
    assert "\n" not in text
    return text


# --- the CSV reader

def test_that_a_motion_written_as_csv_reads_back_as_its_rows(tmp_path, robot, shipped):
    write_csv(tmp_path / "m.csv", shipped.trajectory)  # export-csv's own layout: header 't'
    keys = read_keyframes(tmp_path / "m.csv", robot)
    assert keys.format == KEYFRAMES_CSV_FORMAT and keys.root_pose is None and keys.joint_names == robot.joint_names
    cols = [shipped.trajectory.joint_names.index(j) for j in robot.joint_names]
    np.testing.assert_allclose(keys.q, shipped.trajectory.q[:, cols], atol=1e-6)
    np.testing.assert_allclose(keys.time_s, shipped.trajectory.t, atol=1e-6)
    tr = keys.trajectory(shipped.start)
    assert tr.duration_s == pytest.approx(shipped.duration_s, abs=1e-6)


def test_that_columns_come_in_any_order_and_degrees_are_converted(tmp_path, robot):
    mid = np.degrees((robot.joint_lower + robot.joint_upper) / 2)[::-1]
    names = list(reversed(robot.joint_names))
    path = _write_rows(tmp_path / "d.csv", ["time_s", *names], [[0.2, *mid], [1.0, *(mid + 1.0)]])
    keys = read_keyframes_csv(path, robot, degrees=True)
    assert keys.time_s.tolist() == [0.0, 0.2, 1.0]  # the first keyframe held from 0
    np.testing.assert_allclose(keys.q[:, -1], np.radians([mid[0], mid[0], mid[0] + 1.0]))


def test_that_a_missing_joint_is_named(tmp_path, robot):
    header = ["time_s", *robot.joint_names[1:]]
    path = _write_rows(tmp_path / "k.csv", header, [[0.0, *([0.0] * (len(header) - 1))], [1.0, *([0.0] * (len(header) - 1))]])
    text = _one_line_error(lambda: read_keyframes_csv(path, robot))
    assert f"missing joints {robot.joint_names[0]} " in text


def test_that_an_unknown_joint_is_named(tmp_path, robot):
    header = ["time_s", *robot.joint_names, "tail"]
    path = _write_rows(tmp_path / "k.csv", header, [[0.0, *([0.0] * (len(header) - 1))], [1.0, *([0.0] * (len(header) - 1))]])
    assert "unknown joints tail " in _one_line_error(lambda: read_keyframes_csv(path, robot))


def test_that_times_must_increase_strictly(tmp_path, robot):
    path = _small_csv(tmp_path, robot, times=(0.0, 0.5, 0.5))
    assert "line 4: time 0.5 s after 0.5 s; times must increase strictly" in _one_line_error(lambda: read_keyframes_csv(path, robot))


def test_that_nan_is_refused_naming_the_joint(tmp_path, robot):
    path = _small_csv(tmp_path, robot)
    lines = path.read_text().splitlines()
    cells = lines[2].split(",")
    cells[3] = "nan"
    path.write_text("\n".join([*lines[:2], ",".join(cells), *lines[3:]]) + "\n")
    text = _one_line_error(lambda: read_keyframes_csv(path, robot))
    assert f"line 3: not a finite number: {robot.joint_names[2]}" in text


def test_that_an_angle_past_its_limit_and_text_are_refused(tmp_path, robot):
    assert "lies past its limits" in _one_line_error(lambda: read_keyframes_csv(_small_csv(tmp_path, robot, value=57.0), robot))
    path = _small_csv(tmp_path, robot)
    path.write_text(path.read_text().replace("0.1", "x", 1))
    assert "is not a number" in _one_line_error(lambda: read_keyframes_csv(path, robot))


# --- the MuJoCo keyframe reader: what keyframe_export writes

def test_that_exported_mujoco_keyframes_read_back_with_their_root(tmp_path, robot, shipped):
    keys_written = write_keyframes(tmp_path / "k.xml", robot, shipped.trajectory)
    keys = read_mujoco_keyframes(tmp_path / "k.xml", robot)
    assert keys.format == KEYFRAMES_FORMAT
    cols = [shipped.trajectory.joint_names.index(j) for j in robot.joint_names]
    np.testing.assert_array_equal(keys.q, shipped.trajectory.q[:, cols])
    np.testing.assert_array_equal(keys.time_s, shipped.trajectory.t)
    np.testing.assert_allclose(keys.root_pose, keys_written.qpos[0, :7])
    start = keys.start_posture()
    assert start is not None and start.joints == keys.first_joints()
    # the same keys without the exporter's comment: read the same
    bare = "\n".join(line for line in (tmp_path / "k.xml").read_text().splitlines() if "<!--" not in line)
    (tmp_path / "bare.xml").write_text(bare)
    np.testing.assert_array_equal(read_keyframes(tmp_path / "bare.xml", robot).q, keys.q)


def _keys_xml(tmp_path, body: str, comment: str = ""):
    path = tmp_path / "keys.xml"
    path.write_text(f"<mujoco>{comment}<keyframe>{body}</keyframe></mujoco>\n")
    return path


def test_that_bad_mujoco_keyframes_are_refused_in_one_line(tmp_path, robot, shipped):
    write_keyframes(tmp_path / "k.xml", robot, shipped.trajectory)
    good = read_mujoco_keyframes(tmp_path / "k.xml", robot)
    nq = 7 + robot.n_joints + len(robot.passive_joints)
    row = " ".join(["0"] * nq)
    assert "qpos has 3 numbers" in _one_line_error(lambda: read_mujoco_keyframes(_keys_xml(tmp_path, '<key time="0" qpos="0 0 0"/>'), robot))
    two = f'<key time="0.5" qpos="{row}"/><key name="b" time="0.2" qpos="{row}"/>'
    assert "key 1 (b): time 0.2 s after 0.5 s" in _one_line_error(lambda: read_mujoco_keyframes(_keys_xml(tmp_path, two), robot))
    nan = f'<key time="0" qpos="{row}"/><key time="1" qpos="{row.replace("0", "nan", 8)}"/>'
    assert "key 1: not a finite number" in _one_line_error(lambda: read_mujoco_keyframes(_keys_xml(tmp_path, nan), robot))
    other = _keys_xml(tmp_path, f'<key time="0" qpos="{row}"/>', "<!-- robot-rise/mujoco-keyframes@9: 1 keys -->")
    assert "format is 'robot-rise/mujoco-keyframes@9'" in _one_line_error(lambda: read_mujoco_keyframes(other, robot))
    odd = _keys_xml(tmp_path, f'<key time="0" qpos="{row}" speed="1"/>')
    assert "not attribute speed" in _one_line_error(lambda: read_mujoco_keyframes(odd, robot))
    assert good.q.shape == shipped.trajectory.q.shape


# --- library add

def _library_copy(tmp_path, robot):
    out = tmp_path / "op3"
    shutil.copytree(robot_library_dir(robot), out)
    return out


def _shipped_csv(tmp_path, shipped, *, speed=1.0):
    tr = shipped.trajectory
    rows = [[t / speed, *q] for t, q in zip(tr.t.tolist(), tr.q.tolist())]
    return _write_rows(tmp_path / f"getup_x{speed:g}.csv", ["time_s", *tr.joint_names], rows)


def test_that_library_add_proves_seals_and_indexes_a_shipped_motion_as_csv(tmp_path, capsys, robot, shipped):
    lib_dir = _library_copy(tmp_path, robot)
    path = _shipped_csv(tmp_path, shipped)
    code = main(["library", "add", str(path), "--name", "mine", "--lying", "prone", "--dir", str(lib_dir), "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["proven"] and out["written"] and out["reason"] == "", out["reason"]
    index = json.loads((lib_dir / "index.json").read_text())
    assert index["motions"][-1] == out["row"] and out["row"]["name"] == "mine" and out["row"]["lying"] == "prone"
    lib = load_library(lib_dir)
    m = lib.get("mine")
    assert m.trajectory.report["proven"] is True and seal_problem(m.trajectory) == ""
    assert execution_permit(m.trajectory.report, robot, m.trajectory).allowed
    assert 0.0 < m.connect_until_s < m.duration_s and m.trajectory.root is not None
    assert len(lib.motions) == len(load_library(robot_library_dir(robot)).motions) + 1


def test_that_a_motion_too_fast_to_stand_is_refused_and_nothing_is_written(tmp_path, capsys, robot, shipped):
    lib_dir = _library_copy(tmp_path, robot)
    before = {p.name: p.read_bytes() for p in lib_dir.iterdir()}
    path = _shipped_csv(tmp_path, shipped, speed=3.0)
    code = main(["library", "add", str(path), "--name", "fast", "--lying", "prone", "--dir", str(lib_dir)])
    out = capsys.readouterr().out
    assert code == 1
    assert len(out.splitlines()) == 1 and out.startswith("fast: NOT PROVEN: ") and "fails on the robustness players" in out
    assert out.rstrip().endswith("nothing written")
    assert {p.name: p.read_bytes() for p in lib_dir.iterdir()} == before


def test_that_unproven_writes_it_with_proven_false_and_it_may_not_execute(tmp_path, capsys, robot, shipped):
    lib_dir = _library_copy(tmp_path, robot)
    path = _shipped_csv(tmp_path, shipped, speed=3.0)
    code = main(["library", "add", str(path), "--name", "fast", "--lying", "prone", "--dir", str(lib_dir), "--unproven", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 1 and out["written"] and not out["proven"]
    m = load_library(lib_dir).get("fast")
    assert m.trajectory.report["proven"] is False and m.trajectory.report["problems"] == [out["reason"]]
    assert not execution_permit(m.trajectory.report, robot, m.trajectory).allowed


def test_that_library_add_refuses_a_csv_without_lying_and_a_name_taken(tmp_path, capsys, robot, shipped):
    lib_dir = _library_copy(tmp_path, robot)
    path = _shipped_csv(tmp_path, shipped)
    assert main(["library", "add", str(path), "--name", "mine", "--dir", str(lib_dir)]) == 2
    assert "pass --lying" in capsys.readouterr().err
    assert main(["library", "add", str(path), "--name", MOTION, "--lying", "prone", "--dir", str(lib_dir)]) == 2
    assert f"a motion {MOTION!r} already" in capsys.readouterr().err


def test_that_library_add_takes_exported_mujoco_keyframes_lying_as_their_root_says(tmp_path, capsys, robot, shipped):
    lib_dir = _library_copy(tmp_path, robot)
    write_keyframes(tmp_path / "keys.xml", robot, shipped.trajectory)
    code = main(["library", "add", str(tmp_path / "keys.xml"), "--name", "from_keys", "--dir", str(lib_dir), "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["proven"] and out["lying"] == "prone" and out["format"] == KEYFRAMES_FORMAT, out["reason"]
    assert load_library(lib_dir).get("from_keys").trajectory.report["imported_from"] == {"file": "keys.xml", "format": KEYFRAMES_FORMAT}
