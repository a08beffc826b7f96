"""Progress on stderr (issue 42): a tqdm bar on a terminal, one plain line per stage or step in a pipe.

The helper is tested with a fake clock and a string stream; the commands in child processes with
stderr a pipe, as in a log or CI.
"""

from __future__ import annotations

import io
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from robot_rise.cli._common import MAX_LINE_INTERVAL_S, MIN_LINE_INTERVAL_S, Progress

LINE = re.compile(r"^(?P<label>\w+) \[(?P<elapsed>[\d:]+)\] (?P<text>.+)$")


class FakeClock:
    def __init__(self) -> None:
        self.now_s = 100.0

    def __call__(self) -> float:
        return self.now_s


def _pipe_progress(label: str = "work", total: int | None = None) -> tuple[Progress, io.StringIO, FakeClock]:
    stream, clock = io.StringIO(), FakeClock()
    return Progress(label, total, tty=False, stream=stream, clock=clock), stream, clock


def _run_loop(progress: Progress, clock: FakeClock, steps: int, step_s: float) -> list[float]:
    """Run a loop of ``steps`` reports ``step_s`` apart; the clock times at which a line was written."""
    times = []
    for k in range(1, steps + 1):
        clock.now_s += step_s
        before = progress.stream.tell()
        progress(k, steps)
        if progress.stream.tell() != before:
            times.append(clock.now_s)
    return times


def test_that_a_fast_loop_in_a_pipe_prints_at_most_about_a_line_a_second():
    progress, stream, clock = _pipe_progress()
    times = _run_loop(progress, clock, steps=1000, step_s=0.01)  # 10 s
    lines = stream.getvalue().splitlines()
    assert "\r" not in stream.getvalue()
    assert len(lines) == len(times) <= 12
    assert lines[0].startswith("work [00:00] 1/1000 (0%), ETA ")
    assert lines[-1] == "work [00:10] 1000/1000 (100%)"  # the last step always, with no ETA
    gaps = [b - a for a, b in zip(times, times[1:-1])]  # the last line is not rate-limited
    assert all(g >= MIN_LINE_INTERVAL_S - 1e-9 for g in gaps)


def test_that_a_slow_loop_in_a_pipe_prints_at_least_every_30_s():
    progress, stream, clock = _pipe_progress()
    times = _run_loop(progress, clock, steps=100, step_s=5.0)  # a tenth of the way takes 50 s
    gaps = [b - a for a, b in zip(times, times[1:])]
    assert max(gaps) <= MAX_LINE_INTERVAL_S
    assert len(times) == 1 + 500 // 30 + 1  # the first, one each 30 s, the last
    assert all(LINE.match(line) for line in stream.getvalue().splitlines())


def test_that_a_loop_in_a_pipe_prints_each_tenth_of_the_way_between_the_limits():
    progress, stream, clock = _pipe_progress()
    _run_loop(progress, clock, steps=20, step_s=2.0)
    steps = [int(re.search(r"\] (\d+)/20", line).group(1)) for line in stream.getvalue().splitlines()]
    assert steps == [1, 3, 5, 7, 9, 11, 13, 15, 17, 19, 20]


def test_that_the_eta_in_a_pipe_comes_from_the_rate_of_the_loop():
    progress, stream, clock = _pipe_progress("batch")
    clock.now_s += 60.0  # a stage before the loop does not count in its rate
    progress.stage("sampling postures")
    clock.now_s += 10.0
    progress(1, 4, info="1 proven, 0 failed")
    assert stream.getvalue().splitlines() == ["batch [01:00] sampling postures", "batch [01:10] 1/4 (25%), ETA 00:30, 1 proven, 0 failed"]


def test_that_every_stage_in_a_pipe_is_one_line():
    progress, stream, clock = _pipe_progress("rise")
    for text in ("planning to a frame 3", "filtering a in MuJoCo", "checking robustness"):
        progress.stage(text)  # no rate limit on stages
    clock.now_s += 75.0
    progress.stage("planning to b frame 0")
    assert stream.getvalue() == ("rise [00:00] planning to a frame 3\nrise [00:00] filtering a in MuJoCo\n"
                                 "rise [00:00] checking robustness\nrise [01:15] planning to b frame 0\n")


def test_that_a_second_loop_starts_its_own_lines():
    progress, stream, clock = _pipe_progress("report", 1)
    _run_loop(progress, clock, steps=3, step_s=0.1)
    _run_loop(progress, clock, steps=2, step_s=0.1)  # key frames after the video frames
    steps = [re.search(r"\] (\d+/\d+)", line).group(1) for line in stream.getvalue().splitlines()]
    assert steps == ["1/3", "3/3", "1/2", "2/2"]


def test_that_a_disabled_progress_prints_nothing():
    stream = io.StringIO()
    progress = Progress("work", 3, enabled=False, tty=False, stream=stream)
    progress(1)
    progress.stage("x")
    progress.close()
    assert stream.getvalue() == ""


def test_that_on_a_terminal_a_loop_is_a_tqdm_bar_with_eta():
    stream = io.StringIO()
    with Progress("sampling", 4, tty=True, unit="posture", stream=stream) as progress:
        progress.stage("settling")
        for k in range(1, 5):
            progress(k)
    text = stream.getvalue()
    assert "settling" in text
    assert "\r" in text and "4/4" in text and "posture" in text and "<" in text  # [elapsed<remaining, rate]


def _robot_rise(*argv: str, cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "COLUMNS": "100"}
    return subprocess.run([sys.executable, "-m", "robot_rise", *argv], cwd=cwd, env=env, capture_output=True, text=True,
                          stdin=subprocess.DEVNULL, timeout=120)


@pytest.fixture(scope="module")
def lying(tmp_path_factory) -> tuple[Path, subprocess.CompletedProcess]:
    tmp = tmp_path_factory.mktemp("progress")
    done = _robot_rise("sample", "--kind", "prone", "--n", "2", "--seed", "4", "--out", str(tmp / "lying"), "--json", cwd=tmp)
    return tmp, done


def test_that_sample_in_a_pipe_prints_its_progress_as_lines_on_stderr(lying):
    tmp, done = lying
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["files"] == [str(tmp / "lying" / f"prone_4_00{i}.json") for i in range(2)]  # stdout unchanged
    assert "\r" not in done.stderr
    lines = [line for line in done.stderr.splitlines() if line.startswith("sampling ")]
    assert lines and lines[-1].endswith("] 2/2 (100%)")
    assert all(LINE.match(line) for line in lines)


def test_that_rise_in_a_pipe_prints_its_stages_as_lines_on_stderr(lying):
    tmp, _ = lying
    done = _robot_rise("rise", "--from", str(tmp / "lying" / "prone_4_000.json"), "--out", str(tmp / "rise.json"), "--budget", "2",
                       "--candidates", "1", "--json", cwd=tmp)
    assert done.returncode in (0, 1), done.stderr
    summary = json.loads(done.stdout)  # stdout is the JSON and nothing else
    assert set(summary) >= {"proven", "attempts", "reason"}
    assert "\r" not in done.stderr
    stages = [LINE.match(line) for line in done.stderr.splitlines() if line.startswith("rise [")]
    assert stages and all(stages)
    assert stages[0]["text"].startswith("planning to ")
    if summary["proven"]:
        assert any(m["text"].startswith("filtering ") for m in stages)
