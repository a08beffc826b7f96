"""Fall detection end to end: the MuJoCo twin feeds the emulated OpenCR, the host reads it over the
bus (drivers.imu.OpenCrImu, with sensor noise and bias) and robot_rise.live.fall decides.

Pushed forward, backward, left and right, the twin's OP3 must read FALLING while it falls and
FALLEN, with the lying kind the twin's own root orientation shows, once it has lain still for the
debounce time; standing, a push it withstands and a library get-up must never read FALLING.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import pytest

import drivers.mockbus as mb
from drivers.bus import DynamixelBus
from drivers.clock import FakeClock
from drivers.imu import OpenCrImu
from drivers.mockbus.emulated_imu import EmulatedImu
from drivers.mockbus.plant import ImuNoise, ServoCommand
from drivers.port import open_port
from drivers.servo_map import load_servo_map
from robot_rise.library import load_library, robot_library_dir
from robot_rise.live import (
    FallConfig,
    FallEstimate,
    FallState,
    TorsoAxes,
    detect,
    lying_kind,
    new_tracker,
    step,
)
from robot_rise.model import Robot
from robot_rise.posture import Posture, stand_posture
from robot_rise.sampling import classify_lying, sample_lying_postures
from robot_rise.sim.twin import MujocoTwin

CYCLE_S = 0.01  # the control loop's 100 Hz
NOISE = ImuNoise(gyro_noise_rad_s=0.01, accel_noise_m_s2=0.05, gyro_bias_rad_s=(0.02, -0.01, 0.01),
                 accel_bias_m_s2=(0.1, -0.1, 0.05), orientation_noise_rad=0.005, seed=3)
PUSH_N = 30.0  # [N] for 0.1 s at the torso: topples the twin's OP3 every way (it withstands 15 N)
PUSH_AT_S, PUSH_FOR_S = 0.3, 0.1
_names = itertools.count()


@dataclass
class Run:
    """What a scenario saw, per cycle: the detector's estimate and the twin's truth."""

    estimates: list[FallEstimate]
    true_tilt_rad: list[float]
    true_speed_rad_s: list[float]
    twin: MujocoTwin

    def first(self, state: FallState) -> int | None:
        return next((k for k, e in enumerate(self.estimates) if e.state is state), None)

    def states(self) -> list[FallState]:
        """The sequence of states, repeats removed."""
        return [s for s, _ in itertools.groupby(e.state for e in self.estimates)]

    def true_lying(self) -> str:
        return classify_lying(self.twin.data.qpos[self.twin.index.qpos_root[3:7]])


def _run_on_the_bus(robot: Robot, *, start: Posture | None = None, push_torso_n: tuple[float, float, float] | None = None,
                    seconds: float = 3.0) -> Run:
    """The twin on an emulated bus with the OpenCR; the host reads the IMU every cycle."""
    twin = MujocoTwin(robot, "flat", start=start)
    smap = load_servo_map(robot.directory / "servos.toml")
    clock = FakeClock()
    mock = mb.MockBus({}, baud_rate=smap.bus.baud_rate, clock=clock, plant=mb.ServoFramePlant(twin, smap),
                      imu=EmulatedImu(noise=NOISE))
    url = mb.attach(f"falls{next(_names)}", mock)
    imu = OpenCrImu(DynamixelBus(open_port(url, smap.bus.baud_rate), baud_rate=smap.bus.baud_rate, clock=clock))
    root = twin.index.root_body
    tracker = new_tracker()
    run = Run([], [], [], twin)
    for k in range(round(seconds / CYCLE_S)):
        pushing = push_torso_n is not None and PUSH_AT_S <= k * CYCLE_S < PUSH_AT_S + PUSH_FOR_S
        force = twin.data.xmat[root].reshape(3, 3) @ np.asarray(push_torso_n) if pushing else np.zeros(3)
        twin.data.xfrc_applied[root, :3] = force
        clock.advance(CYCLE_S)
        sample = imu.read()  # the emulator advances the twin to the bus clock, then answers
        assert sample.valid, sample.status
        tracker = step(tracker, sample)
        run.estimates.append(tracker.estimate)
        run.true_tilt_rad.append(twin.state().tilt_rad)
        run.true_speed_rad_s.append(float(np.linalg.norm(twin.imu_state().angular_velocity_rad_s)))
    mb.detach(url.removeprefix("dxlsim://"))
    return run


def test_that_the_twin_feeds_the_imu_gravity_and_no_rotation_at_rest(robot: Robot) -> None:
    twin = MujocoTwin(robot, "flat")
    for _ in range(100):  # the stand keyframe rocks for ~0.8 s before it rests
        twin.advance_joints(CYCLE_S, {})
    s = twin.imu_state()
    assert s.t_s == pytest.approx(1.0)
    assert np.linalg.norm(s.angular_velocity_rad_s) < 0.02
    assert np.linalg.norm(s.specific_force_m_s2) == pytest.approx(9.81, abs=0.05)
    up = np.asarray(s.specific_force_m_s2) / np.linalg.norm(s.specific_force_m_s2)
    assert math.degrees(math.acos(up[2])) == pytest.approx(math.degrees(twin.state().tilt_rad), abs=0.5)


def test_that_the_torso_axes_are_the_robots_forward_left_and_up(robot: Robot) -> None:
    """From the robot itself, no joint named: its stand keyframe shows up, and the lying labels of
    its motion library (start postures prone/supine/left/right) show forward and left."""
    def up_in_torso(p: Posture) -> np.ndarray:
        w, x, y, z = p.root_quat_wxyz
        return np.array([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)])  # R^T e_z

    library = load_library(robot_library_dir(robot))
    ups = {kind: np.mean([up_in_torso(m.start) for m in library.motions if m.lying == kind], axis=0)
           for kind in ("supine", "prone", "left", "right")}
    forward = ups["supine"] - ups["prone"]  # lying on the back, the front faces up
    left = ups["right"] - ups["left"]  # lying on the right side, the left side faces up
    up = up_in_torso(stand_posture(robot))
    axes = TorsoAxes()
    for derived, declared in ((forward, axes.forward), (left, axes.left), (up, axes.up)):
        assert float(derived @ np.asarray(declared)) / np.linalg.norm(derived) > 0.9
    for m in library.motions:
        assert lying_kind(up_in_torso(m.start), axes) == m.lying == classify_lying(m.start.root_quat_wxyz), m.name


@pytest.mark.parametrize("direction", ["forward", "backward", "left", "right"])
def test_that_a_pushed_robot_reads_falling_during_the_fall_then_fallen_with_its_lying_kind(robot: Robot, direction: str) -> None:
    push = {"forward": (PUSH_N, 0, 0), "backward": (-PUSH_N, 0, 0), "left": (0, PUSH_N, 0), "right": (0, -PUSH_N, 0)}
    run = _run_on_the_bus(robot, push_torso_n=push[direction])  # type: ignore[arg-type]
    assert run.states() == [FallState.STANDING, FallState.FALLING, FallState.FALLEN], run.states()
    k_fall = run.first(FallState.FALLING)
    k_impact = next(k for k, tilt in enumerate(run.true_tilt_rad) if tilt > math.radians(80))
    assert k_fall is not None and k_fall * CYCLE_S >= PUSH_AT_S
    assert (k_impact - k_fall) * CYCLE_S >= 0.1, "falling must be known while there is time to go limp"
    if direction in ("left", "right"):  # a side fall: the torso tips about its forward axis, that side down
        up = np.asarray(run.estimates[k_fall].up_torso)
        assert abs(up[1]) > abs(up[0]) and (up[1] < 0) == (direction == "left")
    k_fallen = run.first(FallState.FALLEN)
    assert k_fallen is not None
    last_motion = max(k for k in range(k_fallen) if run.true_speed_rad_s[k] > 0.2)
    assert (k_fallen - last_motion) * CYCLE_S >= FallConfig().still_s - CYCLE_S  # debounced
    assert run.estimates[-1].state is FallState.FALLEN
    assert run.estimates[-1].lying == run.true_lying()  # the twin's truth (after a side fall it rolls onto its back)


@pytest.mark.parametrize("kind", ["left", "right"])
def test_that_a_robot_on_its_side_reads_fallen_on_that_side(robot: Robot, kind: str) -> None:
    """The twin's OP3 rolls onto its back after a side fall; placed on its side it stays there."""
    lying = sample_lying_postures(robot, kind, 1, seed=0)[0]  # type: ignore[arg-type]
    run = _run_on_the_bus(robot, start=lying, seconds=1.5)
    assert FallState.FALLING not in run.states()
    assert run.estimates[-1].state is FallState.FALLEN
    assert run.estimates[-1].lying == kind == run.true_lying()


def test_that_standing_still_and_a_push_the_robot_withstands_never_read_falling(robot: Robot) -> None:
    still = _run_on_the_bus(robot, seconds=3.0)
    assert still.states() == [FallState.STANDING]
    nudged = _run_on_the_bus(robot, push_torso_n=(15.0, 0.0, 0.0), seconds=2.0)
    assert max(nudged.true_tilt_rad) > math.radians(4)  # it did rock
    assert nudged.states() == [FallState.STANDING]


def test_that_a_library_get_up_reads_fallen_then_standing_and_never_falling(robot: Robot) -> None:
    """prone_knees_first replayed on the twin (servo goals straight to the twin), IMU samples from
    the twin with sensor errors: FALLEN prone before it starts, STANDING at the end, never FALLING
    (falling is only looked for from STANDING: a get-up is DOWN, the rising mode)."""
    motion = load_library(robot_library_dir(robot)).get("prone_knees_first")
    traj = motion.trajectory
    twin = MujocoTwin(robot, "flat", start=motion.start)
    columns = [traj.joint_names.index(j) for j in robot.joint_names]
    rng = NOISE.rng()
    tracker = new_tracker()
    estimates = []
    lead_s, hold_s = 1.0, 1.5
    for k in range(round((lead_s + traj.duration_s + hold_s) / CYCLE_S)):
        tau = k * CYCLE_S - lead_s
        commands = {}
        if tau >= 0:
            goal = [float(np.interp(tau, traj.t, traj.q[:, c])) for c in columns]
            commands = {j: ServoCommand(True, g, 5.0) for j, g in zip(robot.joint_names, goal)}
        twin.advance_joints(CYCLE_S, commands)
        tracker = step(tracker, NOISE.apply(twin.imu_state(), rng))
        estimates.append(tracker.estimate)
    states = [s for s, _ in itertools.groupby(e.state for e in estimates)]
    before = [e for e in estimates if e.t_s < lead_s]
    assert before[-1].state is FallState.FALLEN and before[-1].lying == "prone" == motion.lying
    assert FallState.FALLING not in states, states
    assert states[-1] is FallState.STANDING and twin.state().upright
    assert max(e.angular_speed_rad_s for e in estimates) > FallConfig().fall_gyro_rad_s * 0.8  # a brisk get-up


# ---- the detector on synthetic samples (pure code, no physics) ---------------------------------


@dataclass(frozen=True)
class _Sample:
    t_s: float
    angular_velocity_rad_s: tuple[float, float, float]
    specific_force_m_s2: tuple[float, float, float]
    valid: bool = True


def _tip_over(heading_rad: float, *, rate_rad_s: float = 3.0, to_rad: float = math.pi / 2) -> list[_Sample]:
    """Upright 1 s, a turn at ``rate`` about the horizontal torso axis that tips the torso towards
    ``heading`` (0 = forward, pi/2 = left) until ``to_rad``, then 2 s at rest (kinematics only)."""
    axis = np.array([-math.sin(heading_rad), math.cos(heading_rad), 0.0])  # forward tip: about +y
    g = 9.80665
    out, t, angle = [], 0.0, 0.0
    while t < 1.0 + to_rad / rate_rad_s + 2.0:
        moving = 1.0 <= t < 1.0 + to_rad / rate_rad_s
        angle = min(to_rad, max(0.0, (t - 1.0) * rate_rad_s))
        # torso rotated by `angle` about `axis`: world up seen in the torso frame is R^T e_z
        c, s_ = math.cos(angle), math.sin(angle)
        k = axis
        up_world_in_torso = np.array([0, 0, 1.0]) * c - np.cross(k, [0, 0, 1.0]) * s_ + k * k[2] * (1 - c)
        w = tuple(float(v) for v in (k * rate_rad_s if moving else np.zeros(3)))
        out.append(_Sample(t, w, tuple(float(v) for v in g * up_world_in_torso)))
        t = round(t + CYCLE_S, 10)
    return out


@pytest.mark.parametrize("heading_deg,kind", [(0, "prone"), (30, "prone"), (60, "left"), (90, "left"), (120, "left"),
                                              (150, "supine"), (180, "supine"), (210, "supine"), (240, "right"),
                                              (270, "right"), (300, "right"), (330, "prone")])
def test_that_a_fall_in_any_direction_reads_falling_then_fallen_with_the_side_it_lies_on(heading_deg: int, kind: str) -> None:
    estimates = detect(_tip_over(math.radians(heading_deg)))
    states = [s for s, _ in itertools.groupby(e.state for e in estimates)]
    assert states == [FallState.STANDING, FallState.FALLING, FallState.FALLEN]
    fell = next(e for e in estimates if e.state is FallState.FALLING)
    assert fell.tilt_rad < math.radians(45)  # well before it lies
    assert estimates[-1].lying == kind


def test_that_a_slow_lean_or_a_fast_turn_on_the_spot_is_not_a_fall_and_unusable_samples_are_skipped() -> None:
    lean = _tip_over(0.0, rate_rad_s=0.3, to_rad=math.radians(40))
    assert {e.state for e in detect(lean)} == {FallState.STANDING}
    spin = [_Sample(k * CYCLE_S, (0.0, 0.0, 6.0), (0.0, 0.0, 9.80665)) for k in range(200)]  # about the vertical
    assert {e.state for e in detect(spin)} == {FallState.STANDING}
    broken = [_Sample(s.t_s, s.angular_velocity_rad_s, s.specific_force_m_s2, valid=k % 3 != 0)
              for k, s in enumerate(_tip_over(0.0))]
    broken[200] = _Sample(broken[200].t_s, (math.nan, 0.0, 0.0), (0.0, 0.0, 9.8))
    estimates = detect(broken)
    assert len(estimates) == sum(1 for k, _ in enumerate(broken) if k % 3 != 0) - (1 if 200 % 3 else 0)
    assert estimates[-1].state is FallState.FALLEN and estimates[-1].lying == "prone"


def test_that_lying_kind_agrees_with_the_sampler_on_random_orientations() -> None:
    rng = np.random.default_rng(5)
    axes = TorsoAxes()
    for q in rng.normal(size=(200, 4)):
        q /= np.linalg.norm(q)
        w, x, y, z = q
        up = np.array([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)])
        truth = classify_lying(q)
        if truth != "upright":
            assert lying_kind(up, axes) == truth


def test_that_thresholds_out_of_order_are_refused() -> None:
    with pytest.raises(ValueError, match="upright_tilt_rad < fall_tilt_rad"):
        FallConfig(fall_tilt_rad=math.radians(60))
    with pytest.raises(ValueError, match="right-handed"):
        TorsoAxes(forward=(0.0, 1.0, 0.0), left=(1.0, 0.0, 0.0))
