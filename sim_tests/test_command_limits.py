"""Command limits as a value of the core, conform(), the limits rule, and the predicted positions."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from drivers.executor import DEFAULT_RATE_HZ as DRIVER_RATE_HZ
from drivers.executor import ExecutorConfig
from drivers.safety import MAX_VELOCITY_RAD_S, SafetyLimits
from drivers.servo_map import load_servo_map
from robot_rise.errors import FormatError, RobotRiseError
from robot_rise.filter.command_limits import (
    DEFAULT_MAX_SPEED_RAD_S,
    DEFAULT_RATE_HZ,
    LIMIT_MARGIN_RAD,
    SPEED_MARGIN,
    CommandLimits,
    command_limits_for,
    command_limits_of,
    conform,
    match_command_limits,
)
from robot_rise.proof.prediction import (
    PREDICTION_RATE_HZ,
    TILT_TOLERANCE_FLOOR_RAD,
    TOLERANCE_FLOOR_RAD,
    PredictedPositions,
    expected_positions_of,
    predicted_positions,
)
from robot_rise.model import Robot
from robot_rise.posture import stand_posture
from robot_rise.sim.player import Player
from robot_rise.trajectory import Trajectory, read_trajectory, write_trajectory


def _limits(**kw: object) -> CommandLimits:
    base: dict[str, object] = dict(joint_names=("a", "b"), lower_rad=np.array([-1.0, -2.0]),
                                   upper_rad=np.array([1.0, 2.0]))
    return CommandLimits(**{**base, **kw})  # type: ignore[arg-type]


def _fast(robot: Robot) -> Trajectory:
    """The stand posture with two arm joints swung at up to 8 rad/s, on irregular rows."""
    start = stand_posture(robot)
    t = np.concatenate([np.linspace(0.0, 0.5, 7), [0.52, 0.6, 0.9, 1.5]])
    q = np.repeat(start.joint_vector(robot.joint_names)[None, :], t.size, axis=0)
    k = robot.joint_names.index("r_sho_pitch")
    e = robot.joint_names.index("l_el")
    q[:, k] += 0.8 * np.sin(np.pi * t / 0.5)
    q[:, e] += 0.16 * (t >= 0.52)  # one 20 ms jump of 0.16 rad
    return Trajectory(robot.name, robot.joint_names, t, q, start, {"note": "kept"})


def _segment_speeds(tr: Trajectory, limits: CommandLimits) -> np.ndarray:
    cols = limits.columns(tr.joint_names)
    return np.abs(np.diff(tr.q, axis=0)) / np.diff(tr.t)[:, None] / np.asarray(limits.max_speed_rad_s)[cols]


def test_that_the_core_defaults_are_the_numbers_the_driver_enforces(robot: Robot) -> None:
    smap = load_servo_map(robot.directory / "servos.toml")
    assert DEFAULT_RATE_HZ == DRIVER_RATE_HZ == ExecutorConfig().rate_hz
    assert DEFAULT_MAX_SPEED_RAD_S == MAX_VELOCITY_RAD_S == SafetyLimits(smap.lower_rad, smap.upper_rad).max_velocity_rad_s
    limits = command_limits_for(robot)
    cols = limits.columns(smap.joint_names)
    np.testing.assert_array_equal(limits.lower_rad[cols], smap.lower_rad)
    np.testing.assert_array_equal(limits.upper_rad[cols], smap.upper_rad)
    assert limits.max_step_rad[0] == pytest.approx(0.048)  # 4.8 rad/s at 100 Hz


def test_that_conform_slows_only_the_too_fast_segments_and_keeps_the_path(robot: Robot) -> None:
    tr = _fast(robot)
    limits = command_limits_for(robot)
    before = _segment_speeds(tr, limits).max(axis=1)
    out = conform(tr, limits)
    after = _segment_speeds(out, limits)
    assert before.max() > 1.5 and after.max() <= 1.0 - SPEED_MARGIN + 1e-12
    np.testing.assert_array_equal(out.q, tr.q)  # the rows (the path) stay
    slow = before <= 1.0 - SPEED_MARGIN
    np.testing.assert_allclose(np.diff(out.t)[slow], np.diff(tr.t)[slow], rtol=0, atol=1e-12)
    assert np.all(np.diff(out.t)[~slow] > np.diff(tr.t)[~slow])
    assert out.duration_s > tr.duration_s and out.report == tr.report and out.start is tr.start


def test_that_conform_leaves_a_conforming_trajectory_untouched_and_is_idempotent(robot: Robot) -> None:
    limits = command_limits_for(robot)
    once = conform(_fast(robot), limits)
    assert conform(once, limits) is once


def test_that_conform_keeps_targets_inside_the_joint_limits(robot: Robot) -> None:
    tr = _fast(robot)
    limits = command_limits_for(robot)
    k = robot.joint_names.index("head_pan")
    q = np.array(tr.q)
    q[3, k] = limits.upper_rad[k] + 0.002  # a settled posture's 2 mrad past a limit
    out = conform(dataclasses.replace(tr, q=q), limits)
    assert np.all(out.q <= limits.upper_rad - LIMIT_MARGIN_RAD + 1e-15)
    assert np.all(out.q >= limits.lower_rad + LIMIT_MARGIN_RAD - 1e-15)
    assert out.q[3, k] == pytest.approx(limits.upper_rad[k], abs=2e-6)


def test_that_a_conformed_trajectory_still_conforms_after_the_files_rounding(robot: Robot, tmp_path) -> None:
    limits = command_limits_for(robot)
    out = conform(_fast(robot), limits)
    write_trajectory(tmp_path / "t.json", out)
    back = read_trajectory(tmp_path / "t.json")
    assert _segment_speeds(back, limits).max() <= 1.0
    assert np.all(back.q <= limits.upper_rad) and np.all(back.q >= limits.lower_rad)


def test_that_conform_refuses_a_joint_without_limits(robot: Robot) -> None:
    with pytest.raises(RobotRiseError, match="command limits have no joint"):
        conform(_fast(robot), _limits())


def test_that_command_limits_round_trip_through_the_report() -> None:
    for limits in (_limits(), _limits(max_speed_rad_s=np.array([3.0, 2.5]), rate_hz=50.0)):
        back = command_limits_of({"command_limits": limits.to_dict()})
        assert back is not None and back.joint_names == limits.joint_names and back.rate_hz == limits.rate_hz
        np.testing.assert_array_equal(back.max_speed_rad_s, limits.max_speed_rad_s)
        np.testing.assert_array_equal(back.lower_rad, limits.lower_rad)
    assert _limits().to_dict()["max_speed_rad_s"] == 4.8  # one number when every joint shares it


def test_that_a_report_without_command_limits_has_none_and_a_malformed_one_is_named() -> None:
    assert command_limits_of({"proven": True}) is None
    entry = _limits().to_dict()
    with pytest.raises(FormatError, match=r"report.command_limits: missing field 'rate_hz'"):
        command_limits_of({"command_limits": {k: v for k, v in entry.items() if k != "rate_hz"}})
    with pytest.raises(FormatError, match=r"report.command_limits.max_speed_rad_s must be a number"):
        command_limits_of({"command_limits": {**entry, "max_speed_rad_s": "fast"}})
    with pytest.raises(FormatError, match=r"a: lower limit 1.0 is not below upper limit 1.0"):
        command_limits_of({"command_limits": {**entry, "lower_rad": {"a": 1.0, "b": 0.0}}})


def test_that_invalid_command_limits_are_refused() -> None:
    with pytest.raises(RobotRiseError, match="speed limit must be positive"):
        _limits(max_speed_rad_s=0.0)
    with pytest.raises(RobotRiseError, match="rate 0 Hz must be positive"):
        _limits(rate_hz=0)
    with pytest.raises(RobotRiseError, match="lower_rad must be 2 finite numbers"):
        _limits(lower_rad=np.array([0.0]))


def test_that_the_same_limits_and_a_slower_speed_match() -> None:
    assert match_command_limits(_limits(), _limits()).ok
    assert match_command_limits(_limits(), _limits(), speed=0.5).ok
    # the servo map may drive the joints in another order
    swapped = CommandLimits(("b", "a"), np.array([-2.0, -1.0]), np.array([2.0, 1.0]))
    assert match_command_limits(_limits(), swapped).ok


@pytest.mark.parametrize(
    ("executing", "speed", "reason", "hint"),
    [
        (_limits(), 1.5, "--speed 1.5 would stream the trajectory faster than it was proven", "--speed 1 or below"),
        (_limits(rate_hz=50.0), 1.0, "proven for a 100 Hz control rate, not the 50 Hz requested", "use --rate 100"),
        (_limits(max_speed_rad_s=np.array([3.0, 2.0])), 1.0,
         "proven under a 4.8 rad/s command speed limit, the executor enforces 2 rad/s at b", "prove it again"),
        (_limits(upper_rad=np.array([1.0, 1.5])), 1.0,
         "proven with upper limit 2.0000 rad at b, servos.toml says 1.5000 rad", "servo map changed"),
        (CommandLimits(("a",), np.array([-1.0]), np.array([1.0])), 1.0, "limits for joints the servo map lacks: b",
         "servos.toml"),
    ],
    ids=["faster", "other-rate", "other-speed-limit", "other-joint-limits", "missing-joint"],
)
def test_that_other_limits_are_refused_with_a_reason_and_a_hint(executing: CommandLimits, speed: float,
                                                                reason: str, hint: str) -> None:
    match = match_command_limits(_limits(), executing, speed=speed)
    assert not match.ok and reason in match.reason and hint in match.hint


@pytest.fixture(scope="module")
def replay(robot: Robot):
    tr = conform(_fast(robot), command_limits_for(robot))
    return Player(robot, None).play(tr, hold_s=0.5)


def test_that_the_predicted_table_resamples_the_replay_with_a_floor_tolerance(replay) -> None:
    entry = predicted_positions(replay)
    pred = PredictedPositions.from_dict(entry)
    assert pred.joint_names == replay.joint_names
    assert pred.t_s[0] == 0.0 and pred.t_s[-1] <= replay.t[-1] < pred.t_s[-1] + 1 / PREDICTION_RATE_HZ
    np.testing.assert_allclose(np.diff(pred.t_s), 1 / PREDICTION_RATE_HZ, atol=1e-4)
    resampling = np.max(np.abs(pred.at(replay.t) - replay.q), axis=0)
    assert np.all(pred.tolerance_rad >= TOLERANCE_FLOOR_RAD + resampling - 2e-4)
    assert np.all(pred.tolerance_rad <= TOLERANCE_FLOOR_RAD + resampling + 2e-4)  # no ensemble: nothing more
    np.testing.assert_allclose(pred.at(replay.t[5]), replay.q[5], atol=float(resampling.max()) + 1e-4)


def test_that_the_ensembles_spread_widens_the_tolerance_of_the_joints_it_moves(replay) -> None:
    k = replay.joint_names.index("r_knee")
    q = np.array(replay.q)
    q[:, k] += 0.1  # a variant whose knee sits 0.1 rad lower
    variant = dataclasses.replace(replay, q=q)
    plain = PredictedPositions.from_dict(predicted_positions(replay)).tolerance_rad
    wide = PredictedPositions.from_dict(predicted_positions(replay, ensemble=[variant])).tolerance_rad
    assert wide[k] == pytest.approx(plain[k] + 0.1, abs=2e-4)
    np.testing.assert_allclose(np.delete(wide, k), np.delete(plain, k))


def test_that_the_table_predicts_the_torso_tilt_with_the_variants_spread(replay) -> None:
    pred = PredictedPositions.from_dict(predicted_positions(replay))
    assert pred.tilt_rad is not None and pred.tilt_rad.shape == pred.t_s.shape
    np.testing.assert_allclose(np.interp(replay.t, pred.t_s, pred.tilt_rad), replay.tilt_rad, atol=pred.tilt_tolerance_rad)
    assert TILT_TOLERANCE_FLOOR_RAD <= pred.tilt_tolerance_rad < TILT_TOLERANCE_FLOOR_RAD + 0.01
    leaning = dataclasses.replace(replay, tilt_rad=np.asarray(replay.tilt_rad) + 0.3)  # a variant 0.3 rad more bent
    wide = PredictedPositions.from_dict(predicted_positions(replay, ensemble=[leaning]))
    assert wide.tilt_tolerance_rad == pytest.approx(pred.tilt_tolerance_rad + 0.3, abs=2e-4)
    old = {k: v for k, v in predicted_positions(replay).items() if not k.startswith("tilt")}
    assert PredictedPositions.from_dict(old).tilt_rad is None  # a file from before tilts: nothing to watch


def test_that_expected_positions_are_read_from_the_report_or_absent(replay) -> None:
    assert expected_positions_of({"proven": True}) is None
    entry = predicted_positions(replay)
    got = expected_positions_of({"predicted": entry})
    assert got is not None and got.q_rad.shape == (len(entry["t"]), len(replay.joint_names))
    with pytest.raises(FormatError, match="report.predicted: missing field 'tolerance_rad'"):
        expected_positions_of({"predicted": {k: v for k, v in entry.items() if k != "tolerance_rad"}})
    with pytest.raises(FormatError, match="report.predicted: times must increase strictly"):
        expected_positions_of({"predicted": {**entry, "t": entry["t"][::-1]}})
