"""Snapshots of every command's --help and of the error messages people will see.

The expected texts live in ``sim_tests/snapshots/cli/``. After changing a help text or an error
message on purpose, regenerate them and review the diff:

    ROBOT_RISE_UPDATE_SNAPSHOTS=1 .venv/bin/python -m pytest -q sim_tests/test_cli_snapshots.py

Help is formatted at a fixed width (COLUMNS=100) so the terminal does not matter. Temporary paths
are written as ``<tmp>``.
"""

from __future__ import annotations

import argparse
import json
import os
from collections.abc import Iterator
from pathlib import Path

import pytest

from robot_rise.cli import build_parser, main

SNAPSHOTS = Path(__file__).parent / "snapshots" / "cli"
UPDATE = os.environ.get("ROBOT_RISE_UPDATE_SNAPSHOTS", "") not in ("", "0")
HELP_COLUMNS = "100"


def _commands(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()) -> Iterator[tuple[str, ...]]:
    """Every command path of the CLI, sub-commands of sub-commands included."""
    yield path
    seen: set[int] = set()
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                if id(sub) not in seen:  # aliases share one parser
                    seen.add(id(sub))
                    yield from _commands(sub, (*path, name))


COMMANDS = sorted(_commands(build_parser()))

# name -> argv; {tmp} is a fresh temporary directory, {traj} a valid trajectory file in it, {other}
# a trajectory of another robot, {bad} a file that is not JSON. Every case is cheap: each fails
# before anything is simulated or rendered.
ERROR_CASES: dict[str, list[str]] = {
    "unknown_command": ["nope"],
    "render_missing_file": ["render", "{tmp}/missing.json", "--out", "{tmp}/x.mp4"],
    "render_without_out": ["render", "{traj}"],
    "render_unknown_suffix": ["render", "{traj}", "--out", "{tmp}/x.avi"],
    "render_unknown_camera": ["render", "{traj}", "--out", "{tmp}/x.png", "--camera", "nope"],
    "render_odd_mp4_size": ["render", "{traj}", "--out", "{tmp}/x.mp4", "--width", "321"],
    "render_zero_fps": ["render", "{traj}", "--out", "{tmp}/x.gif", "--fps", "0"],
    "render_negative_distance": ["render", "{traj}", "--out", "{tmp}/x.png", "--distance", "-1"],
    "render_other_robot": ["render", "{other}", "--out", "{tmp}/x.png"],
    "render_not_json": ["render", "{bad}", "--out", "{tmp}/x.png"],
    "render_missing_robot_dir": ["render", "{traj}", "--out", "{tmp}/x.png", "--robot", "{tmp}/no-robot"],
    "report_missing_file": ["report", "{tmp}/missing.json", "--out", "{tmp}/r"],
    "library_add_missing_file": ["library", "add", "{tmp}/missing.csv", "--name", "mine", "--lying", "prone", "--dir", "{tmp}/lib"],
    "report_bad_margin": ["report", "{traj}", "--out", "{tmp}/r", "--margin", "1.5"],
    "report_unknown_camera": ["report", "{traj}", "--out", "{tmp}/r", "--camera", "nope"],
    "view_without_display": ["view", "{traj}"],
    "view_missing_file": ["view", "{tmp}/missing.json"],
    "check_missing_file": ["check", "{tmp}/missing.json"],
    "check_posture_missing_file": ["check-posture", "{tmp}/missing.json"],
    "sample_zero_postures": ["sample", "--out", "{tmp}/s", "--n", "0"],
    "demo_missing_robot_dir": ["demo", "--robot", "{tmp}/no-robot", "--out", "{tmp}/d"],
    "plan_missing_posture": ["plan", "--from", "{tmp}/missing.json", "--out", "{tmp}/p.json"],
    "rise_missing_posture": ["rise", "--from", "{tmp}/missing.json", "--out", "{tmp}/r.json"],
    "execute_missing_file": ["execute", "{tmp}/missing.json", "--mock"],
    "bench_unknown_benchmark": ["bench", "nope"],
}


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    try:
        code = main(argv)
    except SystemExit as e:  # argparse: --help and usage errors
        code = e.code if isinstance(e.code, int) else (0 if e.code is None else 2)
    out, err = capsys.readouterr()
    return code, out, err


def _transcript(argv: list[str], code: int, out: str, err: str, tmp: Path) -> str:
    text = f"$ robot-rise {' '.join(argv)}\nexit {code}\n--- stdout\n{out}--- stderr\n{err}"
    return text.replace(str(tmp), "<tmp>")


def _check_snapshot(name: str, text: str) -> None:
    path = SNAPSHOTS / f"{name}.txt"
    if UPDATE:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
        return
    assert path.is_file(), f"no snapshot {path.name}; run with ROBOT_RISE_UPDATE_SNAPSHOTS=1 to write it"
    assert text == path.read_text(), f"{path.name} changed; if on purpose, regenerate with ROBOT_RISE_UPDATE_SNAPSHOTS=1"


def _help_name(path: tuple[str, ...]) -> str:
    return "help_" + ("_".join(path) if path else "robot-rise")


@pytest.mark.parametrize("path", COMMANDS, ids=lambda p: " ".join(p) or "robot-rise")
def test_help_text_matches_its_snapshot(path, capsys, monkeypatch, tmp_path):
    monkeypatch.setenv("COLUMNS", HELP_COLUMNS)
    argv = [*path, "--help"]
    code, out, err = _run(argv, capsys)
    assert code == 0 and err == ""
    assert "usage: robot-rise" in out
    _check_snapshot(_help_name(path), _transcript(argv, code, out, err, tmp_path))


@pytest.fixture
def files(robot, tmp_path) -> dict[str, str]:
    from robot_rise.posture import Posture
    from robot_rise.trajectory import Trajectory, trajectory_to_dict, write_trajectory

    names = robot.joint_names
    start = Posture(robot.name, robot.stand_qpos[:3], robot.stand_qpos[3:7], dict(zip(names, robot.stand_qpos[7:])))
    tr = Trajectory(robot.name, names, [0.0, 0.5], [robot.stand_qpos[7:], robot.stand_qpos[7:]], start)
    write_trajectory(tmp_path / "traj.json", tr)
    other = trajectory_to_dict(tr)
    other["robot"] = "other"
    (tmp_path / "other.json").write_text(json.dumps(other))
    (tmp_path / "bad.json").write_text("{not json")
    return {"tmp": str(tmp_path), "traj": str(tmp_path / "traj.json"), "other": str(tmp_path / "other.json"), "bad": str(tmp_path / "bad.json")}


@pytest.mark.parametrize("case", sorted(ERROR_CASES))
def test_error_message_matches_its_snapshot(case, files, capsys, monkeypatch, tmp_path):
    monkeypatch.setenv("COLUMNS", HELP_COLUMNS)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    argv = [a.format(**files) for a in ERROR_CASES[case]]
    code, out, err = _run(argv, capsys)
    assert code == 2, f"{case}: a usage or input error exits 2, got {code}"
    assert "Traceback" not in err
    assert err.startswith(("error: ", "usage: ")), err
    _check_snapshot(f"error_{case}", _transcript(argv, code, out, err, tmp_path))


def test_no_snapshot_is_left_over_from_a_removed_command_or_case():
    expected = {_help_name(p) for p in COMMANDS} | {f"error_{c}" for c in ERROR_CASES}
    stale = sorted(p.stem for p in SNAPSHOTS.glob("*.txt") if p.stem not in expected)
    if UPDATE:
        for name in stale:
            (SNAPSHOTS / f"{name}.txt").unlink()
        return
    assert not stale, f"stale snapshots {stale}; regenerate with ROBOT_RISE_UPDATE_SNAPSHOTS=1"
