"""The safety layer's pure functions."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.errors import SafetyError
from drivers.safety import (
    ExpectedTilt,
    evaluate_tilt,
    FaultKind,
    SafetyLimits,
    approach_path,
    check_start,
    clamp_step,
    clamp_to_limits,
    evaluate_feedback,
    limp_pwm_ramp,
    safe_target,
)

LO = np.array([-1.0, -0.5, 0.0])
HI = np.array([1.0, 0.5, 2.0])


def _limits(**kw: float) -> SafetyLimits:
    return SafetyLimits(LO, HI, **kw)


def _feedback(**over: object) -> dict:
    n = 3
    base = dict(q_command_rad=np.zeros(n), q_present_rad=np.zeros(n), valid=np.ones(n, bool),
                hardware_error=np.zeros(n, np.int64), temperature_c=np.full(n, 40.0),
                voltage_v=np.full(n, 12.0), consecutive_failures=np.zeros(n, np.int64))
    base.update(over)
    return base


def test_that_targets_are_clamped_into_joint_limits() -> None:
    assert clamp_to_limits(np.array([5.0, -5.0, 1.0]), LO, HI).tolist() == [1.0, -0.5, 1.0]


def test_that_nan_targets_are_refused() -> None:
    with pytest.raises(SafetyError, match="NaN"):
        clamp_to_limits(np.array([np.nan, 0, 0]), LO, HI)


def test_that_a_step_is_limited_per_joint() -> None:
    out = clamp_step(np.array([1.0, -1.0, 0.01]), np.zeros(3), 0.05)
    assert out.tolist() == [0.05, -0.05, 0.01]


def test_that_safe_target_never_leaves_limits_or_exceeds_the_step_on_random_input() -> None:
    rng = np.random.default_rng(0)
    lim = _limits(max_velocity_rad_s=2.0)
    prev = np.array([0.0, 0.0, 1.0])
    for _ in range(2000):
        desired = rng.normal(0, 3, 3)
        cmd, _ = safe_target(desired, prev, lim, 0.01)
        assert np.all(cmd >= LO) and np.all(cmd <= HI)
        assert np.all(np.abs(cmd - prev) <= 0.02 + 1e-12)
        prev = cmd


def test_that_safe_target_reports_whether_it_clamped() -> None:
    lim = _limits(max_velocity_rad_s=2.0)
    assert safe_target(np.array([0.01, 0, 1.0]), np.array([0, 0, 1.0]), lim, 0.01)[1] is False
    assert safe_target(np.array([0.5, 0, 1.0]), np.array([0, 0, 1.0]), lim, 0.01)[1] is True


def test_that_a_far_start_is_flagged_with_the_worst_joint() -> None:
    chk = check_start(np.array([0.0, 0.4, 1.0]), np.array([0.0, 0.0, 1.0]), _limits(start_tolerance_rad=0.1))
    assert (chk.ok, chk.worst_index) == (False, 1) and chk.max_error_rad == pytest.approx(0.4)


def test_that_the_approach_is_smooth_starts_at_present_and_respects_the_speed() -> None:
    lim = _limits(approach_velocity_rad_s=0.5)
    t, q = approach_path(np.array([0.0, 0.0, 0.0]), np.array([1.0, 0.5, 2.0]), 0.1, lim)
    assert np.allclose(q[0], 0) and np.allclose(q[-1], [1.0, 0.5, 2.0])
    speed = np.abs(np.diff(q, axis=0)) / np.diff(t)[:, None]
    assert speed.max() <= 0.5 * 1.01


def test_that_each_fault_kind_is_detected() -> None:
    lim = _limits(max_tracking_error_rad=0.2, max_temperature_c=70, min_voltage_v=10, max_comm_failures=3)
    cases = {
        FaultKind.TRACKING: dict(q_present_rad=np.array([0.0, 0.3, 0.0])),
        FaultKind.HARDWARE: dict(hardware_error=np.array([0, 0, 0x20])),
        FaultKind.TEMPERATURE: dict(temperature_c=np.array([40.0, 71.0, 40.0])),
        FaultKind.VOLTAGE: dict(voltage_v=np.array([9.0, 12.0, 12.0])),
        FaultKind.COMMUNICATION: dict(consecutive_failures=np.array([0, 3, 0])),
    }
    assert evaluate_feedback(lim, **_feedback()) == []
    for kind, over in cases.items():
        faults = evaluate_feedback(lim, **_feedback(**over))
        assert [f.kind for f in faults] == [kind], kind


def test_that_invalid_entries_are_not_judged_except_for_communication() -> None:
    lim = _limits()
    faults = evaluate_feedback(lim, **_feedback(valid=np.array([True, False, True]),
                                                q_present_rad=np.array([0.0, np.nan, 0.0]),
                                                hardware_error=np.array([0, 0x20, 0])))
    assert faults == []


def test_that_the_limp_ramp_decreases_to_zero() -> None:
    ramp = limp_pwm_ramp(885, 1.0, 0.01)
    assert len(ramp) == 100 and ramp[-1] == 0 and np.all(np.diff(ramp) <= 0)


def test_that_bad_limits_are_refused() -> None:
    with pytest.raises(SafetyError):
        SafetyLimits(np.array([1.0]), np.array([0.0]))


def test_that_a_trajectory_far_outside_the_limits_is_flagged_with_joint_sample_and_limit() -> None:
    from drivers.safety import check_limits

    lim = _limits()
    q = np.zeros((4, 3))
    assert check_limits(q, lim).ok
    q[2, 1] = float(lim.upper_rad[1]) + 0.01  # within the tolerance: clamped, not refused
    assert check_limits(q, lim).ok
    q[3, 2] = float(lim.lower_rad[2]) - 0.5
    c = check_limits(q, lim)
    assert not c.ok and (c.joint_index, c.sample_index) == (2, 3)
    assert c.limit_rad == lim.lower_rad[2] and c.max_excess_rad == pytest.approx(0.5)


@pytest.mark.parametrize("field", [{"approach_s": 0.0}, {"limp_s": -1.0}, {"hold_s": -0.1},
                                   {"recovery_attempts": -1}, {"realtime_priority": 0}, {"rate_hz": 5000.0}])
def test_that_bad_executor_settings_are_refused(field: dict) -> None:
    from drivers.executor import ExecutorConfig

    with pytest.raises(SafetyError):
        ExecutorConfig(**field)


def test_that_a_fault_is_found_exactly_when_some_threshold_is_crossed_on_random_feedback() -> None:
    rng = np.random.default_rng(3)
    lim = _limits(max_tracking_error_rad=0.2, max_temperature_c=70, min_voltage_v=10, max_voltage_v=14.8,
                  max_comm_failures=3)
    for _ in range(2000):  # values scattered around every threshold, exact ties included
        valid = rng.random(3) > 0.1
        fb = _feedback(
            q_present_rad=np.where(valid, rng.choice([0.0, 0.1, 0.2, 0.3], 3), np.nan), valid=valid,
            hardware_error=rng.choice([0, 0, 0, 0x20, 0x80], 3),
            temperature_c=np.where(valid, rng.choice([40.0, 70.0, 71.0], 3), np.nan),
            voltage_v=np.where(valid, rng.choice([9.9, 10.0, 12.0, 14.8, 15.0], 3), np.nan),
            consecutive_failures=rng.choice([0, 2, 3], 3))
        v = fb["valid"]
        crossed = bool(np.any(fb["consecutive_failures"] >= 3) or np.any(v & (fb["hardware_error"] != 0))
                       or np.any(v & (np.abs(fb["q_present_rad"]) > 0.2))
                       or np.any(v & (fb["temperature_c"] > 70))
                       or np.any(v & ((fb["voltage_v"] < 10) | (fb["voltage_v"] > 14.8))))
        assert bool(evaluate_feedback(lim, **fb)) == crossed


def test_that_the_limp_ramp_of_several_servos_starts_at_each_limit() -> None:
    ramp = limp_pwm_ramp(np.array([885, 400]), 0.5, 0.01)
    assert ramp.shape == (50, 2) and np.all(ramp[-1] == 0) and np.all(np.diff(ramp, axis=0) <= 0)
    assert abs(ramp[0, 0] - 885 * 49 / 50) <= 1 and abs(ramp[0, 1] - 400 * 49 / 50) <= 1


def test_that_no_command_to_track_leaves_the_tracking_to_the_expected_positions() -> None:
    lim = _limits(max_tracking_error_rad=0.2)
    far = np.array([0.0, 0.9, 0.0])
    assert [f.kind for f in evaluate_feedback(lim, **_feedback(q_present_rad=far))] == [FaultKind.TRACKING]
    assert evaluate_feedback(lim, **_feedback(q_present_rad=far, q_command_rad=None)) == []
    # every other check still runs
    assert [f.kind for f in evaluate_feedback(lim, **_feedback(q_command_rad=None, temperature_c=np.array([80.0, 40, 40])))] \
        == [FaultKind.TEMPERATURE]


def test_that_a_deviation_from_the_expected_positions_faults_only_after_the_debounce() -> None:
    from drivers.safety import evaluate_expected

    expected = np.zeros(3)
    tol = np.array([0.1, 0.1, 0.2])
    count = np.zeros(3, np.int64)
    valid = np.ones(3, bool)
    beyond = np.array([0.0, 0.15, 0.15])  # joint 1 beyond its tolerance, joint 2 within its wider one
    for cycle in range(1, 3):
        count, faults = evaluate_expected(beyond, expected, tol, valid, count, 3)
        assert faults == [] and count.tolist() == [0, cycle, 0]
    count, faults = evaluate_expected(beyond, expected, tol, valid, count, 3)
    assert [(f.kind, f.index) for f in faults] == [(FaultKind.TRACKING, 1)]
    assert faults[0].value == pytest.approx(0.15) and faults[0].limit == 0.1
    assert "from its expected position for 3 cycles (tolerance 0.100 rad)" in faults[0].message
    # back within: the count restarts; not read: it is kept
    count, _ = evaluate_expected(np.zeros(3), expected, tol, valid, np.array([2, 2, 2]), 3)
    assert count.tolist() == [0, 0, 0]
    count, _ = evaluate_expected(np.array([0.0, np.nan, 0.0]), expected, tol, np.array([True, False, True]),
                                 np.array([0, 2, 0]), 3)
    assert count.tolist() == [0, 2, 0]


def test_that_malformed_expected_positions_are_refused() -> None:
    from drivers.safety import ExpectedPositions

    t = np.array([0.0, 0.5])
    q = np.zeros((2, 3))
    assert ExpectedPositions(t, q, np.full(3, 0.1)).debounce_cycles(0.01) == 3
    assert ExpectedPositions(t, q, np.full(3, 0.1)).debounce_cycles(0.05) == 1  # at least one cycle
    for bad in (dict(t_s=t[::-1]), dict(q_rad=np.zeros((3, 3))), dict(tolerance_rad=np.zeros(3)),
                dict(tolerance_rad=np.full(2, 0.1)), dict(q_rad=np.full((2, 3), np.nan))):
        with pytest.raises(SafetyError, match="expected positions"):
            ExpectedPositions(**{"t_s": t, "q_rad": q, "tolerance_rad": np.full(3, 0.1), **bad})


def test_that_a_torso_off_its_expected_tilt_is_falling_only_after_the_debounce() -> None:
    expected = ExpectedTilt(np.array([0.0, 1.0]), np.array([1.5, 0.1]), 0.2, debounce_s=0.03)
    assert expected.at(0.5) == pytest.approx(0.8) and expected.debounce_cycles(0.01) == 3
    count, faults = evaluate_tilt(0.85, expected.at(0.5), 0.2, 0, 3)
    assert (count, faults) == (0, [])
    for k in (1, 2):
        count, faults = evaluate_tilt(1.6, 0.8, 0.2, count, 3)
        assert count == k and not faults
    count, faults = evaluate_tilt(np.nan, 0.8, 0.2, count, 3)  # not read: the count is kept
    assert count == 2 and not faults
    count, faults = evaluate_tilt(1.6, 0.8, 0.2, count, 3)
    assert count == 3 and [f.kind for f in faults] == [FaultKind.FALLING]
    assert "torso tilted 92 deg where the proof expects 46 +- 11 deg" in faults[0].message


def test_that_a_malformed_expected_tilt_is_refused() -> None:
    with pytest.raises(SafetyError, match="shapes"):
        ExpectedTilt(np.array([0.0, 1.0]), np.array([0.1]), 0.2)
    with pytest.raises(SafetyError, match="increase strictly"):
        ExpectedTilt(np.array([1.0, 0.0]), np.array([0.1, 0.2]), 0.2)
    with pytest.raises(SafetyError, match="tolerance must be positive"):
        ExpectedTilt(np.array([0.0, 1.0]), np.array([0.1, 0.2]), 0.0)


def test_that_a_servo_ahead_of_its_prediction_towards_its_goal_is_not_a_fault_but_one_behind_or_past_it_is() -> None:
    """Issue 41: the band runs from the expected (loaded, lagging) position to the goals; an
    unloaded servo that follows its goals exactly is inside it, a blocked or pushed one is not."""
    from drivers.safety import band_deviation, evaluate_expected

    expected = np.array([0.0, 0.0, 0.0])
    goal_before, goal_now = np.array([0.30, -0.30, 0.30]), np.array([0.31, -0.31, 0.31])
    tol = np.full(3, 0.1)
    on_goal = np.array([0.31, -0.305, 0.15])  # at the goal, between, half way: all inside the band
    assert band_deviation(on_goal, expected, goal_before, goal_now).tolist() == [0.0, 0.0, 0.0]
    count, faults = evaluate_expected(on_goal, expected, tol, np.ones(3, bool), np.full(3, 5, np.int64), 3,
                                      (goal_before, goal_now))
    assert faults == [] and count.tolist() == [0, 0, 0]
    # behind the prediction (blocked, moving the other way) and pushed past the goal: out of the band
    off = np.array([-0.15, -0.45, 0.31])
    assert band_deviation(off, expected, goal_before, goal_now) == pytest.approx([0.15, 0.14, 0.0])
    count = np.zeros(3, np.int64)
    for _ in range(3):
        count, faults = evaluate_expected(off, expected, tol, np.ones(3, bool), count, 3, (goal_before, goal_now))
    assert [(f.kind, f.index) for f in faults] == [(FaultKind.TRACKING, 0), (FaultKind.TRACKING, 1)]
    # without goals the band is the expected position alone, as before
    assert band_deviation(on_goal, expected).tolist() == pytest.approx([0.31, 0.305, 0.15])
