"""Tests of the energy benchmark's files (robot_rise.bench.energy*): the lying60 problem cache and the --out results."""

from __future__ import annotations

import json
from dataclasses import asdict
from types import SimpleNamespace

import numpy as np
import pytest

from robot_rise.errors import FormatError
from robot_rise.model import load_robot
from robot_rise.bench import energy as be
from robot_rise.bench import energy_problems as ep
from robot_rise.cli import main as cli_main
from robot_rise.posture import posture_to_dict
from robot_rise.validity import ValidityChecker


@pytest.fixture(scope="module")
def setup():
    robot = load_robot()
    checker = ValidityChecker(robot, "flat")
    return robot, checker, ep.crossed_problems(robot, checker, kinds=("crossed_arms",), n=1)[0]


def _cache(problem, per_kind, **extra):
    rows = [{"kind": "supine", "variant": i, "goal_rank": i, "goal_frame": f"m@{i}", "start": posture_to_dict(problem.start),
             "goal": posture_to_dict(problem.goal)} for i in range(per_kind["supine"])]
    return {**extra, "key": {"seed": 1, "per_kind": per_kind}, "library_digest": "0" * 16, "problems": rows}


def test_that_the_lying60_cache_gives_each_problem_its_goal_rank_without_global_state(setup, tmp_path):
    robot, checker, p = setup
    per_kind = {"supine": 2}
    path = tmp_path / "lying.json"
    path.write_text(json.dumps(_cache(p, per_kind)))
    out = ep.cached_lying60(robot, 1, per_kind, str(path))
    assert [(q.kind, q.variant, q.goal_rank, q.goal_frame) for q in out] == [("supine", 0, 0, "m@0"), ("supine", 1, 1, "m@1")]
    assert not hasattr(ep, "LYING60_GOAL_RANKS")
    assert ep.CrossedProblem("k", 0, p.start, p.goal).goal_rank == 0  # crossed-limb problems: the nearest, no frame


def test_that_a_lying60_cache_from_before_the_format_string_is_read_with_a_warning(setup, tmp_path, caplog):
    robot, checker, p = setup
    per_kind = {"supine": 1}
    path = tmp_path / "old.json"
    path.write_text(json.dumps(_cache(p, per_kind)))  # no "format": as out/lying60_seed1.json was written
    with caplog.at_level("WARNING"):
        out = ep.cached_lying60(robot, 1, per_kind, str(path))
    assert len(out) == 1 and "has no format string" in caplog.text


def test_that_a_lying60_cache_of_another_format_or_without_its_fields_is_refused(setup, tmp_path):
    robot, checker, p = setup
    per_kind = {"supine": 1}
    path = tmp_path / "other.json"
    path.write_text(json.dumps(_cache(p, per_kind, format="robot-rise/bench-energy@1")))
    with pytest.raises(FormatError, match="format is 'robot-rise/bench-energy@1', expected 'robot-rise/lying-problems@1'"):
        ep.cached_lying60(robot, 1, per_kind, str(path))
    data = _cache(p, per_kind, format=ep.LYING_PROBLEMS_FORMAT)
    del data["problems"][0]["goal"]
    path.write_text(json.dumps(data))
    with pytest.raises(FormatError, match="problem 0 lacks goal"):
        ep.cached_lying60(robot, 1, per_kind, str(path))
    path.write_text("{not json")
    with pytest.raises(FormatError, match="not a JSON file"):
        ep.cached_lying60(robot, 1, per_kind, str(path))


def test_that_a_new_lying60_cache_carries_its_format_and_reads_back_silently(setup, tmp_path, monkeypatch, caplog):
    robot, checker, p = setup
    per_kind = {"supine": 1}
    sampled = [ep.CrossedProblem("supine", 0, p.start, p.goal, 1, "m@3")]
    monkeypatch.setattr(ep, "lying60_problems", lambda *a, **k: sampled)  # sampling settles postures for minutes
    path = tmp_path / "new.json"
    assert ep.cached_lying60(robot, 1, per_kind, str(path)) == sampled
    assert json.loads(path.read_text())["format"] == ep.LYING_PROBLEMS_FORMAT
    monkeypatch.setattr(ep, "lying60_problems", lambda *a, **k: pytest.fail("the cache was not reused"))
    with caplog.at_level("WARNING"):
        back = ep.cached_lying60(robot, 1, per_kind, str(path))
    assert [(q.goal_rank, q.goal_frame) for q in back] == [(1, "m@3")] and "no format string" not in caplog.text


def test_that_a_lying60_goal_is_the_connecting_posture_rise_selects(setup, monkeypatch):
    import robot_rise.sampling
    from robot_rise.library import load_library, robot_library_dir
    from robot_rise.rise import RiseContext, select_goal

    robot, _, _ = setup
    start = load_library(robot_library_dir(robot)).motions[0].start
    monkeypatch.setattr(robot_rise.sampling, "sample_lying", lambda robot, kind, n, seed: SimpleNamespace(postures=[start] * n))
    (problem,) = ep.lying60_problems(robot, per_kind={"supine": 1})  # sampling settles postures for minutes
    sel = select_goal(RiseContext.build(robot, "flat"), start)
    assert f"{problem.goal_frame} (candidate {problem.goal_rank})" == sel.source
    assert np.array_equal(problem.goal.root_pos, sel.goal.root_pos) and problem.goal.joints == sel.goal.joints


def _row(planner="energy"):
    return be.BenchRow(planner, "crossed", "crossed_arms", 0, True, 0.1, 0.2, 1.0, 0.0, 0.0, 5.0, 1.0, "")


def _results(runs, **extra):
    return {**extra, "args": {}, "wall_s": 1.0, "runs": runs}


def test_that_merge_tables_a_results_file_of_its_format(tmp_path, capsys):
    path = tmp_path / "r.json"
    path.write_text(json.dumps(_results([asdict(_row()), asdict(_row("rrt_blossom"))], format=be.BENCH_ENERGY_FORMAT)))
    assert cli_main(["bench", "energy", "--merge", str(path)]) == 0
    assert "| crossed_arms | energy | 1/1 (100 %)" in capsys.readouterr().out
    assert cli_main(["bench", "energy", "--merge", str(path), "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    assert [r["planner"] for r in rows] == ["energy", "rrt_blossom"] and rows[0] == json.loads(json.dumps(asdict(_row())))


@pytest.mark.parametrize(
    "doc, message",
    [
        (_results([asdict(_row())]), "format is None, expected 'robot-rise/bench-energy@1'"),
        (_results([asdict(_row())], format="robot-rise/bench-planning@1"), "format is 'robot-rise/bench-planning@1', expected"),
        ({"format": be.BENCH_ENERGY_FORMAT}, "no runs field"),
        (_results([{k: v for k, v in asdict(_row()).items() if k != "jerk"}], format=be.BENCH_ENERGY_FORMAT), "run 0 lacks jerk"),
        (_results([{**asdict(_row()), "colour": "red"}], format=be.BENCH_ENERGY_FORMAT), "run 0 has unknown fields colour"),
        (_results([[1, 2]], format=be.BENCH_ENERGY_FORMAT), "run 0 is not an object"),
    ],
)
def test_that_merge_refuses_a_bad_results_file_in_one_line_with_a_hint(tmp_path, capsys, doc, message):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(FormatError, match=message):
        be.load_rows([str(path)])
    assert cli_main(["bench", "energy", "--merge", str(path)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and err[0].startswith("error: ") and message in err[0] and err[1].startswith("hint: ")


def test_that_the_results_file_carries_its_format_and_merges_back(tmp_path, monkeypatch, capsys):
    out = tmp_path / "out.json"
    monkeypatch.setattr(be, "run_benchmark", lambda **kw: [kw["progress"](_row()) or _row()])  # the files, not the planners
    assert cli_main(["bench", "energy", "--out", str(out)]) == 0
    assert json.loads(out.read_text())["format"] == be.BENCH_ENERGY_FORMAT
    back = be.load_rows([str(out)])
    assert [(r.planner, r.kind, r.jerk) for r in back] == [("energy", "crossed_arms", 5.0)]


def test_that_merge_names_a_file_it_cannot_read_in_one_line(tmp_path, capsys):
    assert cli_main(["bench", "energy", "--merge", str(tmp_path / "absent.json")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and err[0].startswith("error: ") and "absent.json: cannot be read" in err[0]
