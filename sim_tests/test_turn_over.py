"""Turn-over strategies: a roll or a tip that ends lying, followed by a robot's own get-up where a lying kind has none (issue 15)."""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from robot_rise.authoring import robustness_players
from robot_rise.authoring.build import build_library
from robot_rise.authoring.turn_over import landing
from robot_rise.errors import FormatError
from robot_rise.library import default_library_dir, load_library, load_strategies, read_strategy
from robot_rise.model import load_robot
from robot_rise.paths import configs_dir
from robot_rise.sampling import classify_lying

ROBOT = load_robot()
STRATEGIES = {s.name: s for s in load_strategies()}
TURN_OVERS = [s for s in STRATEGIES.values() if s.lands is not None]


def test_the_shipped_turn_overs_cover_the_back_and_both_sides_and_land_on_the_front() -> None:
    assert {s.lying for s in TURN_OVERS} == {"supine", "left", "right"}
    assert {s.lands for s in TURN_OVERS} == {"prone"}


def test_a_strategy_file_names_a_lying_kind_it_lands_in(tmp_path: Path) -> None:
    src = json.loads((configs_dir() / "strategies" / "supine_roll_onto_front.json").read_text())
    for bad in ("upside_down", "supine"):
        (tmp_path / "s.json").write_text(json.dumps({**src, "lands": bad}))
        with pytest.raises(FormatError, match="lands .* must be a lying kind other than 'supine'"):
            read_strategy(tmp_path / "s.json")


@pytest.mark.slow
def test_the_roll_lands_on_the_front_at_rest_on_every_player_as_authored_and_says_when_it_does_as_clamped() -> None:
    roll = STRATEGIES["supine_roll_onto_front"]
    players = robustness_players(ROBOT)
    got = landing(ROBOT, roll, players)
    assert got.landed_s is not None and len(got.per_player_s) == len(players) and got.turn is not None and got.start is not None
    # replayed independently on the nominal body (the path starts where it lies) up to the landing time: prone there, at rest
    rec = players[0].play(got.turn, hold_s=0.0)
    k = int(np.searchsorted(rec.t, got.landed_s))
    assert classify_lying(rec.root_pose[k, 3:]) == "prone"
    assert np.linalg.norm(rec.root_vel[k:, 3:], axis=1).max() < 0.5 and np.abs(rec.qd[k:]).max() < 0.5
    # ... and it had not yet landed at the roll's last keyframe
    assert classify_lying(rec.root_pose[int(np.searchsorted(rec.t, roll.keyframes[-1].t_s)), 3:]) != "prone" or \
        np.abs(rec.qd[int(np.searchsorted(rec.t, roll.keyframes[-1].t_s))]).max() > 0.5
    wrong = dataclasses.replace(roll, lands="left")  # it does not end on its side
    missed = landing(ROBOT, wrong, players[:1])
    assert missed.landed_s is None and "not at rest left" in missed.reason


def test_turn_overs_are_not_authored_as_get_ups(tmp_path: Path) -> None:
    from robot_rise.authoring import author_library, motion_specs

    assert not {s.name for s in motion_specs(ROBOT)} & {s.name for s in TURN_OVERS}
    failures: dict[str, str] = {}
    assert author_library(tmp_path, ROBOT, names=["supine_roll_onto_front"], failures=failures) == []
    assert "a turn-over" in failures["supine_roll_onto_front"] and not (tmp_path / "supine_roll_onto_front.json").exists()


def test_a_build_refuses_a_strategy_name_there_is_not(tmp_path: Path) -> None:
    from robot_rise.errors import ConfigError

    with pytest.raises(ConfigError, match="no strategy named supine_rol_onto_front"):
        build_library(ROBOT, tmp_path / "motions", names=["supine_rol_onto_front"])
    assert not (tmp_path / "motions" / "index.json").exists()


def test_a_build_skips_a_turn_over_where_the_kind_has_its_own_motion_and_keeps_the_library(tmp_path: Path) -> None:
    lib = tmp_path / "motions"
    shutil.copytree(default_library_dir(), lib)
    before = (lib / "index.json").read_text()
    report = build_library(ROBOT, lib, names=["supine_roll_onto_front"])
    assert "supine_roll_onto_front" in report.skipped and "not needed: lying supine has" in report.skipped["supine_roll_onto_front"]
    assert not report.written and not report.failed
    assert json.loads((lib / "index.json").read_text())["motions"] == json.loads(before)["motions"]
    assert json.loads((lib / "build_report.json").read_text())["skipped"][0]["name"] == "supine_roll_onto_front"


def test_a_build_says_why_a_turn_over_has_nothing_to_follow_it(tmp_path: Path) -> None:
    lib = tmp_path / "motions"
    shutil.copytree(default_library_dir(), lib)
    index = json.loads((lib / "index.json").read_text())
    index["motions"] = [r for r in index["motions"] if r["lying"] not in ("supine", "prone")]  # no back and no front get-up
    (lib / "index.json").write_text(json.dumps(index))
    report = build_library(ROBOT, lib, names=["supine_roll_onto_front"])
    assert report.failed == {"supine_roll_onto_front": "lands prone, and the robot has no proven prone get-up to follow it"}
    assert "supine" in report.kinds_without_motion()


@pytest.mark.slow
def test_a_build_fills_a_lying_kind_without_a_motion_with_the_turn_over_and_a_proven_get_up(tmp_path: Path) -> None:
    """The OP3 library without its supine motions: the roll onto the front, then a prone get-up the
    library has (its rows as proven), proven as one motion and written; the library has a supine
    motion again, and it plays the get-up's rows after the roll."""
    lib = tmp_path / "motions"
    shutil.copytree(default_library_dir(), lib)
    index = json.loads((lib / "index.json").read_text())
    index["motions"] = [r for r in index["motions"] if r["lying"] != "supine"]
    (lib / "index.json").write_text(json.dumps(index))
    report = build_library(ROBOT, lib, names=["supine_roll_onto_front"])
    assert len(report.written) == 1, report.failed
    row = report.written[0]
    assert row["turn_over"] == "supine_roll_onto_front" and row["lying"] == "supine"
    then = row["name"].removeprefix("supine_roll_onto_front_then_")
    assert then in {r["name"] for r in index["motions"] if r["lying"] == "prone"}
    library = load_library(lib)
    motion, get_up = library.get(row["name"]), library.get(then)
    assert motion.trajectory.report["proven"] and "supine" not in report.kinds_without_motion()
    tail = motion.trajectory.q[-len(get_up.trajectory.t):]
    assert np.allclose(tail, get_up.trajectory.q, atol=1e-6)  # the get-up as proven on this robot, not re-authored
    assert motion.duration_s > get_up.trajectory.duration_s + 2.0  # after the roll has landed


@pytest.mark.slow
def test_wolfgang_gets_a_proven_motion_from_its_side_by_tipping_onto_its_front(shared_robots, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """Wolfgang-OP as its team published it, with its servo map (MX-64 arms, MX-106 legs, XH540
    knees on a 4S LiPo), has no side get-up of its own: the tip off its right side, legs apart
    (its 106 mm feet are as wide as its hips are apart), then its prone get-up, is proven as one
    motion, the path and the get-up slowed where the whole needs it."""
    from robot_rise.authoring.turn_over import TURN_OVER_SLOWING
    from robot_rise.robot_import import import_robot

    model, _ = shared_robots["wolfgang"]
    robot = load_robot(import_robot(model, tmp_path / "wolfgang", servos=Path(__file__).parent / "data" / "wolfgang_servos.toml").directory)
    assert robot.supply_voltage_v == 14.8
    report = build_library(robot, tmp_path / "motions", names=["prone_elbow_knees", "right_tip_onto_front"])
    rows = {r["name"]: r for r in report.written}
    assert "prone_elbow_knees" in rows, report.failed
    tip = rows.get("right_tip_onto_front_then_prone_elbow_knees")
    assert tip is not None and tip["lying"] == "right" and tip["turn_over"] == "right_tip_onto_front", report.failed
    written = load_library(tmp_path / "motions").get(tip["name"]).trajectory.report
    assert written["proven"]
    slowing = (written["turn_over"]["path_time_factor"], written["turn_over"]["get_up_time_factor"])
    assert slowing in TURN_OVER_SLOWING
    assert set(report.kinds_without_motion()) == {"supine", "left"}
