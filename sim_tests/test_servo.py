"""Servo model: envelope, position-mode torque, per-joint arrays, and the composed MuJoCo servo."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

import robot_rise.servo as servo
from robot_rise.errors import ConfigError
from robot_rise.model import compose, load_robot, model_index
from robot_rise.servo import SERVO_DATASHEETS, envelope_ratio, position_mode_torque, servo_arrays, servo_datasheet, torque_limits


def test_every_name_in_all_resolves() -> None:
    for name in servo.__all__:
        assert hasattr(servo, name), name


def test_unknown_servo_model_lists_the_known_models() -> None:
    with pytest.raises(ConfigError, match="XM430-W350"):
        servo_datasheet("XM999")


def test_xm430_effective_stiffness_matches_the_datasheet_derivation() -> None:
    s = servo_datasheet("XM430-W350")
    # (800 / 128) PWM/tick * 651.9 tick/rad * 4.1 N m / 885 = 18.9 N m/rad (facts: ~19)
    assert s.position_gain_nm_per_rad(12.0) == pytest.approx(18.87, abs=0.05)
    assert s.saturation_error_rad() == pytest.approx(0.217, abs=0.002)


def test_envelope_falls_linearly_to_zero_at_no_load_speed() -> None:
    lo, hi = torque_limits(np.array(4.1), np.array(4.8), np.array([0.0, 2.4, 4.8]))
    assert hi == pytest.approx([4.1, 2.05, 0.0])
    assert lo == pytest.approx([-4.1, -6.15, -8.2])


def test_braking_torque_has_more_room_than_driving_torque() -> None:
    r_drive = envelope_ratio(np.array(2.0), np.array(2.0), 4.1, 4.8)
    r_brake = envelope_ratio(np.array(-2.0), np.array(2.0), 4.1, 4.8)
    assert r_drive > r_brake


def test_position_mode_torque_never_leaves_the_envelope() -> None:
    rng = np.random.default_rng(0)
    s = servo_datasheet("XM430-W350")
    e = rng.uniform(-1, 1, 1000)
    w = rng.uniform(-s.no_load_speed_rad_s, s.no_load_speed_rad_s, 1000)
    tau = position_mode_torque(e, np.zeros(1000), w, kp_nm_per_rad=18.9, stall_torque_nm=4.1, no_load_speed_rad_s=s.no_load_speed_rad_s)
    assert np.all(envelope_ratio(tau, w, 4.1, s.no_load_speed_rad_s) <= 1.0 + 1e-9)


def test_servo_arrays_scale_torque_and_speed_with_voltage() -> None:
    specs = (SERVO_DATASHEETS["XM430-W350"], SERVO_DATASHEETS["XL430-W250"])
    a12, a6 = servo_arrays(specs, 12.0), servo_arrays(specs, 6.0)
    assert a6.stall_torque_nm == pytest.approx(a12.stall_torque_nm / 2)
    assert a6.no_load_speed_rad_s == pytest.approx(a12.no_load_speed_rad_s / 2)
    assert a6.back_emf_damping_nm_s == pytest.approx(a12.back_emf_damping_nm_s)


def test_mujoco_servo_reproduces_the_dc_motor_torque_speed_line() -> None:
    """Drive one joint at a saturated goal and compare actuator force minus back-EMF with tau_s (1 - w/w0)."""
    robot = load_robot()
    m = compose(robot, None)
    d = mujoco.MjData(m)
    idx = model_index(m, robot)
    arrays = servo_arrays(robot.servo_datasheets(), 12.0)
    j = robot.joint_index("head_pan")
    d.qpos[idx.qpos_root[3]] = 1.0
    m.opt.gravity[:] = 0
    d.ctrl[idx.actuators[j]] = robot.joint_upper[j]  # far goal: duty saturated at +1
    for _ in range(20):
        mujoco.mj_step(m, d)
    w_all = d.qvel[idx.dof_joints]
    tau_all = arrays.motor_torque(d.actuator_force[idx.actuators], w_all)
    w, tau = float(w_all[j]), float(tau_all[j])
    expected = arrays.stall_torque_nm[j] * (1 - w / arrays.no_load_speed_rad_s[j])
    assert w > 0.1
    assert tau == pytest.approx(expected, rel=1e-6)
    assert arrays.ratio(tau_all, w_all)[j] == pytest.approx(1.0, abs=1e-6)
    assert math.isfinite(tau)
