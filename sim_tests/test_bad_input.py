"""Issue 41 (part 4): malformed input gets one clear line naming the file or flag, exit 2, nothing
written; no traceback, no hang, no nonsense accepted."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from robot_rise.model import load_robot
from robot_rise.posture import stand_posture
from robot_rise.trajectory import Trajectory, trajectory_to_dict


def _run(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "robot_rise", *args], capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL)


def _one_line_error(r: subprocess.CompletedProcess, *needles: str) -> None:
    assert r.returncode == 2, (r.returncode, r.stdout, r.stderr)
    assert "Traceback" not in r.stderr
    first = r.stderr.strip().splitlines()[-1] if "usage:" in r.stderr else r.stderr.strip().splitlines()[0]
    for n in needles:
        assert n in r.stderr, (n, r.stderr)
    assert len(first) < 400


def _hold(robot, seconds: float = 0.5) -> dict:  # type: ignore[no-untyped-def]
    start = stand_posture(robot)
    q = start.joint_vector(robot.joint_names)
    t = np.linspace(0.0, seconds, 3)
    return trajectory_to_dict(Trajectory(robot.name, robot.joint_names, t, np.tile(q, (3, 1)), start))


@pytest.fixture(scope="module")
def op3():  # type: ignore[no-untyped-def]
    return load_robot()


def test_json_nested_fifty_thousand_deep_is_one_line_not_a_recursion_error(tmp_path: Path) -> None:
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 60000 + "]" * 60000)
    _one_line_error(_run("check-posture", str(deep)), str(deep), "nested too deep")
    _one_line_error(_run("check", str(deep)), str(deep), "nested too deep")


def test_binary_garbage_a_fifo_and_a_directory_name_the_file(tmp_path: Path) -> None:
    garbage = tmp_path / "garbage.json"
    garbage.write_bytes(bytes(range(256)) * 4)
    _one_line_error(_run("check", str(garbage)), str(garbage), "not UTF-8 text")
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)
    _one_line_error(_run("check-posture", str(fifo), timeout=30), str(fifo), "not a regular file")  # would block forever if opened
    _one_line_error(_run("check", str(tmp_path)), str(tmp_path), "not a regular file")


def test_a_trajectory_lasting_a_million_seconds_is_refused_before_any_replay(tmp_path: Path, op3) -> None:  # type: ignore[no-untyped-def]
    obj = _hold(op3)
    obj["t"][-1] = 1e6
    path = tmp_path / "long.json"
    path.write_text(json.dumps(obj))
    for cmd in ("check", "render"):
        args = [cmd, str(path)] + (["--out", str(tmp_path / "r.mp4")] if cmd == "render" else [])
        _one_line_error(_run(*args, timeout=60), str(path), "lasts 1e+06 s")
    assert not (tmp_path / "r.mp4").exists()


def test_times_written_as_text_are_refused(tmp_path: Path, op3) -> None:  # type: ignore[no-untyped-def]
    obj = _hold(op3)
    obj["t"] = [str(x) for x in obj["t"]]
    path = tmp_path / "text_times.json"
    path.write_text(json.dumps(obj))
    _one_line_error(_run("check", str(path)), str(path), "'t' must hold numbers only")


@pytest.mark.parametrize(
    ("args", "flag"),
    [
        (["rise", "--from", "x.json", "--out", "y.json", "--budget", "0"], "--budget"),
        (["rise", "--from", "x.json", "--out", "y.json", "--budget", "-5"], "--budget"),
        (["rise", "--from", "x.json", "--out", "y.json", "--budget", "nan"], "--budget"),
        (["rise", "--from", "x.json", "--out", "y.json", "--margin", "-1"], "--margin"),
        (["render", "x.json", "--out", "y.mp4", "--width", "0"], "--width"),
        (["batch", "--out", "store", "--jobs", "0"], "--jobs"),
        (["batch", "--out", "store", "--seed", "-1"], "--seed"),
        (["check-posture", "x.json", "--tolerance", "nan"], "--tolerance"),
        (["check-posture", "x.json", "--tolerance", "-1"], "--tolerance"),
    ],
)
def test_flags_take_only_meaningful_values(tmp_path: Path, args: list[str], flag: str) -> None:
    r = subprocess.run([sys.executable, "-m", "robot_rise", *args], capture_output=True, text=True, timeout=60, cwd=tmp_path)
    _one_line_error(r, f"argument {flag}: must be")
    assert list(tmp_path.iterdir()) == []  # nothing written (no half-made store)


def test_global_flags_may_follow_the_command() -> None:
    r = _run("robot", "show", "--debug")
    assert r.returncode == 0 and "robot op3" in r.stdout, r.stderr
    r = _run("robot", "show", "-v")
    assert r.returncode == 0, r.stderr


def test_the_version_is_printed() -> None:
    from importlib.metadata import version

    r = _run("--version")
    assert r.returncode == 0 and r.stdout.strip() == f"robot-rise {version('robot-rise')}"


def test_a_model_mujoco_warns_about_leaves_no_mujoco_log_in_the_working_directory(tmp_path: Path) -> None:
    """Issue 41: MuJoCo's warnings go to the log, not to a MUJOCO_LOG.TXT where the user stands."""
    model = tmp_path / "warned.xml"
    model.write_text('<mujoco><worldbody><body><joint type="hinge" range="nan nan"/><geom size="0.1"/></body></worldbody></mujoco>')
    r = subprocess.run([sys.executable, "-c", "import robot_rise.model, mujoco, sys\n"
                        "try:\n    mujoco.MjModel.from_xml_path(sys.argv[1])\nexcept ValueError:\n    pass\n", str(model)],
                       cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert "NaN" in r.stderr  # said, through logging
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
