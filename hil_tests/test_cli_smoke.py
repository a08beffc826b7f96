"""Operator commands end to end on the emulated bus: servos, execute, mockbus serve."""

from __future__ import annotations

import re
import select
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import drivers.mockbus as mb
from drivers.servo_map import load_servo_map
from drivers.session import mock_url_for
from robot_rise.cli import main
from robot_rise.model import Robot, load_robot
from robot_rise.trajectory import Trajectory, write_trajectory
from robot_rise.posture import stand_posture
from robot_rise.seal import sealed


@pytest.fixture(scope="module")
def robot() -> Robot:
    return load_robot()


def _trajectory(robot: Robot, path: Path, report: dict) -> Path:
    """0.4 s of arm motion from the stand keyframe."""
    start = stand_posture(robot)
    t = np.linspace(0.0, 0.4, 5)
    q = np.repeat(start.joint_vector(robot.joint_names)[None, :], t.size, axis=0)
    k = robot.joint_names.index("r_sho_pitch")
    q[:, k] += np.linspace(0.0, 0.2, t.size)
    write_trajectory(path, sealed(Trajectory(robot.name, robot.joint_names, t, q, start, report)))  # a "proven" report is the test's own proof: sealed
    return path


def _proven_report(robot: Robot, **overrides: object) -> dict:
    return {"proven": True, "robot": robot.name, "robot_digest": robot.digest(), "scene": "flat", **overrides}


def test_that_servos_scan_on_the_mock_finds_every_mapped_servo(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["servos", "scan", "--mock"]) == 0
    out = capsys.readouterr().out
    assert "20 servo(s) answered; 0 of the map missing" in out
    assert "XM430-W350" in out


@pytest.mark.parametrize("action", ["scan", "status"])
def test_that_a_wrong_baud_rate_is_named_when_nothing_answers(action: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["servos", action, "--mock", "--baud", "57600"]) == 1
    err = capsys.readouterr().err
    assert "hint: no servo answered at 57600 bit/s (servos.toml says 2000000)" in err and "Traceback" not in err


def test_that_execute_on_the_mock_streams_a_proven_trajectory_and_exits_zero(
        robot: Robot, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _trajectory(robot, tmp_path / "arm.json", _proven_report(robot))
    log = tmp_path / "run.csv"
    assert main(["execute", str(path), "--mock", "--yes", "--log", str(log)]) == 0
    out = capsys.readouterr().out
    assert "proven on robot op3 in scene flat" in out
    assert "completed" in out
    rows = log.read_text().splitlines()
    assert rows[0].startswith("cycle,t_s,cmd_") and len(rows) > 40  # >= 0.4 s at 100 Hz


def test_that_execute_refuses_an_unproven_trajectory_with_a_hint(
        robot: Robot, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _trajectory(robot, tmp_path / "raw.json", {"proven": False, "robot": robot.name})
    assert main(["execute", str(path), "--mock", "--yes"]) == 2
    err = capsys.readouterr().err
    assert "error: the trajectory's report does not say it was proven" in err
    assert "--allow-unproven" in err


def test_that_execute_refuses_a_report_without_the_robot_name(
        robot: Robot, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _trajectory(robot, tmp_path / "anon.json", {"proven": True})
    assert main(["execute", str(path), "--mock", "--yes"]) == 2
    assert "report.robot missing" in capsys.readouterr().err


def test_that_execute_refuses_a_trajectory_proven_on_changed_robot_files(
        robot: Robot, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _trajectory(robot, tmp_path / "old.json", _proven_report(robot, robot_digest="0" * 64))
    assert main(["execute", str(path), "--mock", "--yes"]) == 2
    err = capsys.readouterr().err
    assert "proven on another version of robot 'op3'" in err and "000000000000..." in err


@pytest.mark.parametrize(
    ("edit", "args", "message"),
    [
        (lambda q, k: q.__setitem__((2, k), 50.0), [], "trajectory leaves the joint limits: r_sho_pitch = 50.000 rad"),
        (None, ["--approach", "-1"], "approach time -1.0 s must be positive"),
        (None, ["--rt-priority", "500"], "real-time priority 500 outside 1..99"),
        (None, ["--log", "/proc/no/such/dir/run.csv"], "cannot write the log /proc/no/such/dir/run.csv"),
        (None, ["--rate", "5"], "rate 5 Hz outside 20..2000 Hz"),
    ],
    ids=["far-outside-limits", "negative-approach", "bad-priority", "unwritable-log", "rate-too-low"],
)
def test_that_bad_execute_input_is_one_error_line_before_anything_moves(
        robot: Robot, tmp_path: Path, capsys: pytest.CaptureFixture[str], edit, args, message) -> None:
    path = _trajectory(robot, tmp_path / "arm.json", _proven_report(robot))
    if edit is not None:
        from robot_rise.trajectory import read_trajectory

        tr = read_trajectory(path)
        q = np.array(tr.q)
        edit(q, robot.joint_names.index("r_sho_pitch"))
        write_trajectory(path, sealed(Trajectory(tr.robot, tr.joint_names, tr.t, q, tr.start, tr.report)))  # as if proven so: the limits must still catch it
    assert main(["execute", str(path), "--mock", "--yes", *args]) == 2
    out, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1 and message in lines[0], err
    assert "Traceback" not in err and "preflight" not in out  # refused before the bus was touched


def test_that_execute_refuses_a_rate_the_bus_cannot_carry(
        robot: Robot, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _trajectory(robot, tmp_path / "arm.json", _proven_report(robot))
    assert main(["execute", str(path), "--mock", "--yes", "--rate", "1000"]) == 2
    err = capsys.readouterr().err
    assert [ln for ln in err.splitlines() if ln.startswith("error:")] == [
        ln for ln in err.splitlines() if "more than the bus allows" in ln]
    assert "hint: lower --rate" in err


def test_that_answering_no_at_the_prompt_moves_nothing(
        robot: Robot, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    path = _trajectory(robot, tmp_path / "arm.json", _proven_report(robot))
    monkeypatch.setattr("builtins.input", lambda prompt: "n")
    before = set(mb.protocol_dxlsim._BUSES)
    assert main(["execute", str(path), "--mock"]) == 2
    assert "aborted; nothing moved" in capsys.readouterr().out
    (name,) = set(mb.protocol_dxlsim._BUSES) - before
    emulator = mb.attached(name)
    assert emulator is not None and not any(s.torque_on for s in emulator.servos.values())


def test_that_execute_with_the_twin_reports_the_simulated_robot_upright(
        robot: Robot, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _trajectory(robot, tmp_path / "arm.json", _proven_report(robot))
    assert main(["execute", str(path), "--mock", "--twin", "--yes"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"twin: [\d.]+ s simulated; torso tilt [\d.]+ deg, .*: upright", out), out


def test_that_read_posture_raises_a_driver_error_when_a_servo_is_silent(
        robot: Robot, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    smap = load_servo_map(robot.directory / "servos.toml")
    url = mock_url_for(smap, wire_timing=False)
    emulator = mb.attached(url.removeprefix("dxlsim://"))
    assert emulator is not None
    emulator.faults.silence(3)
    out_file = tmp_path / "pose.json"
    assert main(["servos", "read-posture", "--port", url, "--out", str(out_file)]) == 2
    err = capsys.readouterr().err
    assert "error: no present position from servo(s) [3]; no posture written" in err
    assert not out_file.exists()


def test_that_read_posture_writes_the_present_angles(robot: Robot, tmp_path: Path) -> None:
    out_file = tmp_path / "pose.json"
    assert main(["servos", "read-posture", "--mock", "--out", str(out_file)]) == 0
    assert '"robot-rise/posture@1"' in out_file.read_text()


def test_that_read_posture_takes_the_root_pose_from_a_given_posture(robot: Robot, tmp_path: Path) -> None:
    from robot_rise.posture import Posture, read_posture, write_posture

    lying = Posture(robot.name, np.array([0.3, -0.2, 0.05]), np.array([0.0, 1.0, 0.0, 0.0]),
                    dict(zip(robot.joint_names, robot.stand_qpos[7:])))
    root_file, out_file = tmp_path / "root.json", tmp_path / "pose.json"
    write_posture(root_file, lying)
    assert main(["servos", "read-posture", "--mock", "--root-from", str(root_file), "--out", str(out_file)]) == 0
    got = read_posture(out_file, robot)
    np.testing.assert_allclose(got.root_pos, lying.root_pos)
    np.testing.assert_allclose(np.abs(got.root_quat_wxyz), np.abs(lying.root_quat_wxyz))


def test_that_read_posture_refuses_a_bad_root_file_before_touching_the_bus(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad, out_file = tmp_path / "root.json", tmp_path / "pose.json"
    bad.write_text('{"format": "robot-rise/trajectory@1"}')
    assert main(["servos", "read-posture", "--mock", "--root-from", str(bad), "--out", str(out_file)]) == 2
    assert "expected 'robot-rise/posture@1'" in capsys.readouterr().err
    assert not out_file.exists()


def test_that_mockbus_serve_prints_a_device_that_servos_scan_can_open(
        capsys: pytest.CaptureFixture[str]) -> None:
    def as_from_a_shell() -> None:
        # earlier tests of this process (Ray, gRPC threads) may leave SIGINT blocked or ignored,
        # which a child inherits; a server started from a shell has it delivered
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
        signal.signal(signal.SIGINT, signal.SIG_DFL)

    proc = subprocess.Popen([sys.executable, "-m", "robot_rise", "mockbus", "serve", "--duration", "60"],
                            stdout=subprocess.PIPE, text=True, preexec_fn=as_from_a_shell)
    try:
        assert proc.stdout is not None
        ready, _, _ = select.select([proc.stdout], [], [], 60.0)
        line = proc.stdout.readline() if ready else ""
        match = re.match(r"mock bus on (/dev/\S+): 20 servos \(op3\) at 2000000 bit/s", line)
        assert match, line
        assert main(["servos", "scan", "--port", match.group(1)]) == 0
        out = capsys.readouterr().out
        assert "no latency timer" in out and "low-latency ioctl not supported" in out
        assert "20 servo(s) answered" in out
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(30)  # a loaded 2-core machine has taken over 10 s to wind the server down
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(10)
            pytest.fail("mockbus serve did not stop within 30 s of Ctrl-C")
        if proc.stdout is not None:
            proc.stdout.close()
    assert proc.returncode == 0


def _limits_entry(robot: Robot, **over: object) -> dict:
    from robot_rise.filter.command_limits import command_limits_for

    return command_limits_for(robot, **over).to_dict()  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("limits", "args", "message", "hint"),
    [
        ({"rate_hz": 50.0}, [], "the trajectory was proven for a 50 Hz control rate, not the 100 Hz requested",
         "hint: use --rate 50"),
        ({"max_speed_rad_s": 2.0}, [], "proven under a 2 rad/s command speed limit, the executor enforces 4.8 rad/s",
         "hint: prove it again"),
        ({}, ["--speed", "1.5"], "--speed 1.5 would stream the trajectory faster than it was proven",
         "hint: use --speed 1 or below"),
    ],
    ids=["other-rate", "other-speed-limit", "faster"],
)
def test_that_execute_refuses_a_trajectory_proven_under_other_command_limits(
        robot: Robot, tmp_path: Path, capsys: pytest.CaptureFixture[str], limits, args, message, hint) -> None:
    path = _trajectory(robot, tmp_path / "arm.json", _proven_report(robot, command_limits=_limits_entry(robot, **limits)))
    assert main(["execute", str(path), "--mock", "--yes", *args]) == 2
    out, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1 and message in lines[0], err
    assert hint in err and "preflight" not in out  # refused before the bus was touched


def test_that_execute_runs_a_file_without_command_limits_with_a_warning(
        robot: Robot, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _trajectory(robot, tmp_path / "old.json", _proven_report(robot))
    assert main(["execute", str(path), "--mock", "--yes"]) == 0
    out, err = capsys.readouterr()
    assert "warning: the trajectory's report records no command limits" in err and "completed" in out
    assert "tracking watched" not in out


@pytest.fixture(scope="module")
def predicted_arm(robot: Robot, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The arm motion, proven on the model, with its command limits and predicted positions."""
    from robot_rise.proof import prove
    from robot_rise.proof.prediction import predicted_positions
    from robot_rise.trajectory import read_trajectory

    path = _trajectory(robot, tmp_path_factory.mktemp("arm") / "arm.json", {})
    traj = read_trajectory(path)
    rec, _, proof = prove(robot, traj, scene="flat")
    assert proof.proven, proof.problems
    write_trajectory(path, sealed(traj.with_report(**proof.to_dict(), command_limits=_limits_entry(robot),
                                                   predicted=predicted_positions(rec))))  # what was just proven
    return path


def test_that_execute_on_the_twin_watches_the_proofs_predicted_positions(
        predicted_arm: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["execute", str(predicted_arm), "--mock", "--twin", "--yes"]) == 0
    out, err = capsys.readouterr()
    assert re.search(r"tracking watched against the band from the proof's predicted positions to the goals \(tolerance [\d.]+\.\.[\d.]+ rad\)", out)
    assert "safety-clamped cycles 0" in out and "completed" in out and "warning" not in err
    match = re.search(r"largest distance outside the band from the proof's predicted positions to the goals [\d.]+ rad \(([\d.]+) of its tolerance\)", out)
    assert match and float(match.group(1)) < 1.0, out


def test_that_execute_at_another_speed_watches_the_command_not_the_prediction(
        predicted_arm: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["execute", str(predicted_arm), "--mock", "--yes", "--speed", "0.5"]) == 0
    out = capsys.readouterr().out
    assert "note: tracking watched against the command (0.35 rad), not the proof's predicted positions" in out
    assert "largest distance outside the band" not in out
