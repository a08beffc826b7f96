"""The physics twin moves the mock servos: executor -> mock bus -> MuJoCo twin."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from drivers.clock import FakeClock
from drivers.executor import Executor, ExecutorConfig
from drivers.mockbus import JointPlant, Plant, ServoCommand, ServoFramePlant
from drivers.safety import SafetyLimits
from drivers.servo_map import load_servo_map
from drivers.session import connect, mock_url_for
from drivers.startup import engage, preflight
from robot_rise.model import Robot
from robot_rise.posture import stand_posture
from robot_rise.sim.twin import MujocoTwin

ARM_JOINTS = ("l_sho_pitch", "r_sho_pitch", "l_el", "r_el")


@pytest.fixture(scope="module")
def twin(robot: Robot) -> MujocoTwin:
    return MujocoTwin(robot, "flat")


def test_that_the_twin_satisfies_the_mock_bus_joint_plant_protocol(twin: MujocoTwin) -> None:
    assert isinstance(twin, JointPlant) and not isinstance(twin, Plant)
    motions = twin.advance_joints(0.004, {})
    assert set(motions) == set(twin.robot.joint_names)
    assert twin.time_s == pytest.approx(0.004)


def test_that_a_reversed_servo_reports_the_mirrored_joint_angle_through_the_servo_map(robot: Robot) -> None:
    smap = load_servo_map(robot.directory / "servos.toml")
    servos = list(smap.servos)
    k = next(i for i, s in enumerate(servos) if s.joint == "l_el")
    servos[k] = dataclasses.replace(servos[k], direction=-1, zero_offset=0.1)
    smap = dataclasses.replace(smap, servos=tuple(servos))
    twin = MujocoTwin(robot, None)
    plant = ServoFramePlant(twin, smap)
    q = dict(zip(robot.joint_names, twin.joint_positions_rad))
    motions = plant.advance(0.0, {})
    assert motions[servos[k].id].position_rad == pytest.approx(-(q["l_el"] + 0.1))
    assert servos[k].from_servo_frame(motions[servos[k].id].position_rad) == pytest.approx(q["l_el"])
    # a goal in the servo frame reaches the twin as the joint angle it means
    start = {s.id: s.to_servo_frame(q[s.joint]) for s in servos}
    goal_joint = q["l_el"] - 0.3
    commands = {sid: ServoCommand(True, a, 5.0) for sid, a in start.items()}
    commands[servos[k].id] = ServoCommand(True, servos[k].to_servo_frame(goal_joint), 5.0)
    for _ in range(50):
        plant.advance(0.01, commands)
    assert twin.joint_positions_rad[robot.joint_names.index("l_el")] == pytest.approx(goal_joint, abs=0.03)


def test_that_a_powered_servo_drives_its_joint_to_the_goal(robot: Robot) -> None:
    twin = MujocoTwin(robot, None)  # no ground: the robot floats, joints move freely
    q = dict(zip(robot.joint_names, twin.joint_positions_rad))
    goal = q["r_sho_pitch"] + 0.3
    commands = {j: ServoCommand(True, a, 5.0) for j, a in q.items()}
    commands["r_sho_pitch"] = ServoCommand(True, goal, 5.0)
    for _ in range(50):
        motions = twin.advance_joints(0.01, commands)
    assert motions["r_sho_pitch"].position_rad == pytest.approx(goal, abs=0.03)


def test_that_a_trajectory_streamed_to_the_mock_bus_moves_the_simulated_joints(robot: Robot) -> None:
    start = stand_posture(robot)
    twin = MujocoTwin(robot, "flat", start=start)
    smap = load_servo_map(robot.directory / "servos.toml")
    clock = FakeClock()
    url = mock_url_for(smap, initial_rad=start.joints, clock=clock, plant=twin)
    t = np.linspace(0.0, 1.0, 11)
    q0 = start.joint_vector(robot.joint_names)
    q = np.repeat(q0[None, :], t.size, axis=0)
    cols = [robot.joint_names.index(j) for j in ARM_JOINTS]
    delta = np.array([0.5, -0.5, 0.4, -0.4])
    q[:, cols] += (t / t[-1])[:, None] * delta[None, :]
    with connect(smap, url) as conn:
        preflight(conn.group)
        engage(conn.group, watchdog_s=0.1)
        limits = SafetyLimits(smap.lower_rad, smap.upper_rad)
        report = Executor(conn.group, limits, ExecutorConfig(rate_hz=100.0, hold_s=0.5)).run(robot.joint_names, t, q)
    assert report.completed, report.faults
    assert twin.time_s >= 1.4  # the simulation advanced with the bus clock
    final = twin.joint_positions_rad
    np.testing.assert_allclose(final[cols], q[-1, cols], atol=0.05)
    state = twin.state()
    assert state.tilt_rad < 0.3  # moving the arms did not topple the standing robot
    assert state.torso_height_m > 0.8 * robot.stand_height_m
    # the mock reported the simulated angles back to the host: tracking stayed tight
    assert report.max_tracking_error_rad < 0.15


def test_that_the_start_posture_is_held_until_the_first_servo_is_torqued_on(robot: Robot) -> None:
    unpowered = {j: ServoCommand(False, 0.0, 5.0) for j in robot.joint_names}
    held = MujocoTwin(robot, "flat")
    limp = MujocoTwin(robot, "flat", hold_start=False)
    for _ in range(25):
        held.advance_joints(0.02, unpowered)
        limp.advance_joints(0.02, unpowered)
    knee = robot.joint_names.index("l_knee")
    start_knee = stand_posture(robot).joints["l_knee"]
    assert held.joint_positions_rad[knee] == pytest.approx(start_knee, abs=0.08)  # servo compliance under load
    assert abs(limp.joint_positions_rad[knee] - start_knee) > 0.2  # without support it folds


@pytest.mark.slow
def test_that_a_library_get_up_streamed_through_the_mock_bus_stands_the_twin_up(robot: Robot) -> None:
    from robot_rise.paths import configs_dir
    from robot_rise.trajectory import read_trajectory

    path = configs_dir() / "motions" / robot.name / "prone_knees_first.json"
    traj = read_trajectory(path)
    twin = MujocoTwin(robot, "flat", start=traj.start)
    smap = load_servo_map(robot.directory / "servos.toml")
    url = mock_url_for(smap, initial_rad=traj.start.joints, clock=FakeClock(), plant=twin)
    with connect(smap, url) as conn:
        preflight(conn.group)
        engage(conn.group, watchdog_s=0.1)
        limits = SafetyLimits(smap.lower_rad, smap.upper_rad)
        report = Executor(conn.group, limits, ExecutorConfig(rate_hz=100.0, hold_s=2.0)).run(
            traj.joint_names, traj.t, traj.q)
    assert report.completed, report.faults
    assert twin.state().upright
