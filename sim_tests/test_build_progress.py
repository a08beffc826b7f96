"""Issue 42: `library build` says what it is doing while it runs (a line per strategy started and
finished, and one at least every PROGRESS_EVERY_S while a strategy runs)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

import robot_rise.authoring.build as build
from robot_rise.model import load_robot


def test_a_build_prints_a_line_per_strategy_and_a_heartbeat_while_one_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def slow_author(out, robot, *, names, strategies, failures):  # type: ignore[no-untyped-def]
        time.sleep(0.35)  # a strategy that takes a while (minutes, for real)
        failures[names[0]] = "fell (torso tilted 80 deg)"
        return []

    monkeypatch.setattr(build, "author_library", slow_author)
    monkeypatch.setattr(build, "PROGRESS_EVERY_S", 0.1)
    lines: list[str] = []
    report = build.build_library(load_robot(), tmp_path / "motions", names=["prone_elbow_knees", "prone_knees_first"], progress=lines.append)
    assert report.failed.keys() == {"prone_elbow_knees", "prone_knees_first"}
    started = sorted(line.split()[1] for line in lines if line.startswith(("[1/2]", "[2/2]")))
    assert started == ["prone_elbow_knees", "prone_knees_first"] and lines[0].startswith("[1/2] ")
    assert any("prone_elbow_knees: not proven: fell (torso tilted 80 deg)" in line for line in lines)
    beats = [line for line in lines if "building prone_elbow_knees" in line and "s so far" in line]
    assert len(beats) >= 2  # 0.35 s at a beat every 0.1 s


def test_the_cli_prints_the_progress_on_stderr_and_the_table_on_stdout(tmp_path: Path) -> None:
    import subprocess
    import sys

    r = subprocess.run(
        [sys.executable, "-m", "robot_rise", "library", "build", "--only", "supine_roll_onto_front", "--out", str(tmp_path / "lib")],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert "library of op3" in r.stdout and "supine_roll_onto_front" in r.stdout
    assert "... building" not in r.stdout
