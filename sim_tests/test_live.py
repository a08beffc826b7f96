"""Live get-up end to end: where the body lies, getup, the health check, the guard's pushes.

The physics twin moves the emulated servos and feeds the emulated OpenCR (ID 200) on the mock bus;
the host reads the joints (sync read) and the IMU (with noise and bias) over the bus, as on the
robot, on a simulated clock (``robot-rise getup/guard --mock --twin``).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

import numpy as np
import pytest

import drivers.mockbus as mb
from robot_rise.cli import main
from robot_rise.cli.cmd_getup import LiveSession, open_live_session
from robot_rise.live import (
    ExecutionResult,
    FallState,
    GetUpConfig,
    GuardEventKind,
    GuardState,
    Health,
    HealthLimits,
    PlannedGetUp,
    PostureEstimate,
    PostureEstimator,
    get_up,
    guard_step,
    health_limits_for_supply,
    health_problems,
    new_tracker,
    root_quat_from_up,
    up_of_quat,
    watch,
)
from robot_rise.model import Robot
from robot_rise.posture import Posture
from robot_rise.sampling import classify_lying, sample_lying_postures
from robot_rise.trajectory import Trajectory

PUSH_FIELDS = {"max_tilt_deg", "lying", "first_command_after_s", "standing", "standing_after_s", "attempts"}


def _args(**kw: object) -> argparse.Namespace:
    base = {"mock": True, "twin": True, "port": None, "robot": None, "scene": "flat", "baud": None, "seed": 0, "budget": 5.0}
    return argparse.Namespace(**{**base, **kw})


@contextlib.contextmanager
def _lying_session(robot: Robot, kind: str, seed: int = 0) -> Iterator[tuple[LiveSession, Posture]]:
    start = sample_lying_postures(robot, kind, 1, seed=seed)[0]  # type: ignore[arg-type]
    with open_live_session(_args(seed=seed), start=start) as s:
        yield s, start


def _run_cli(*argv: str) -> tuple[int, str]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(list(argv))
    return code, out.getvalue()


# ---- where the body lies -----------------------------------------------------------------------


def test_that_the_root_orientation_from_gravity_shows_that_gravity_whatever_the_yaw() -> None:
    rng = np.random.default_rng(2)
    for u in rng.normal(size=(100, 3)):
        u /= np.linalg.norm(u)
        for yaw in (0.0, 1.3, -2.9):
            assert np.allclose(up_of_quat(root_quat_from_up(u, yaw)), u, atol=1e-9)
    with pytest.raises(ValueError, match="non-zero"):
        root_quat_from_up((0.0, 0.0, 0.0))


@pytest.mark.parametrize("kind,seed", [("supine", 0), ("prone", 0), ("left", 0), ("right", 0), ("right", 3)])
def test_that_the_estimate_of_a_lying_twin_has_its_kind_and_orientation_from_the_bus(robot: Robot, kind: str, seed: int) -> None:
    """Joints from one sync read, gravity from the OpenCR (noise 0.05 m/s^2, bias 0.1 m/s^2): the
    settled estimate's up direction is within a degree of the twin's, joints within a tick. Right
    side, seed 3: the model settled freely rolls 14 deg towards its back; the IMU's tilt is kept."""
    with _lying_session(robot, kind, seed) as (s, _):
        tracker, why = watch(s.io, new_tracker(), until=(FallState.FALLEN,), timeout_s=3.0, cycle_s=0.01)
        assert not why and tracker.estimate.lying == kind
        truth = s.io.true_posture()
        assert classify_lying(truth.root_quat_wxyz) == kind  # the twin still lies as sampled
        est = s.estimator.estimate(s.io.read_joints(), tracker.estimate.up_torso, truth=truth)
    assert est.lying == kind and est.valid
    assert est.settled == (seed == 0)  # seed 3: rolled away, the IMU's orientation kept
    assert est.error is not None
    assert est.error.imu_orientation_deg < 3.0  # the IMU alone (the 3 deg)
    assert est.error.orientation_deg < (1.0 if est.settled else 3.0)  # settled: contacts match
    assert est.error.joint_max_rad < 2 * 2 * math.pi / 4096  # ticks
    assert abs(est.error.root_height_m) < 0.005


# ---- getup -------------------------------------------------------------------------------------


def test_that_getup_on_the_twin_from_lying_prone_ends_standing_with_a_report_per_attempt() -> None:
    # whole proofs: this session's start proof cache is cold (the composed default: the slow test below)
    code, out = _run_cli("getup", "--mock", "--twin", "--lying", "prone", "--seed", "3", "--json", "--whole-proofs")
    report = json.loads(out)
    assert code == 0 and report["standing"] and not report["gave_up"]
    first = report["attempts"][0]
    assert first["lying"] == "prone" and first["proven"] and first["executed"] and first["standing"]
    assert first["estimate"]["error"]["orientation_deg"] < 3.0
    assert first["first_command_after_s"] > 0 and first["standing_s"] > first["first_command_s"]
    assert {"started_s", "fallen_s", "plan_cpu_s", "motion", "why", "health"} <= set(first)


def test_that_a_standing_robot_is_left_alone() -> None:
    code, out = _run_cli("getup", "--mock", "--twin", "--json", "--whole-proofs")
    report = json.loads(out)
    assert code == 0 and report["already_standing"] and report["attempts"] == []


@pytest.mark.slow
def test_that_getup_composes_with_the_cached_start_proofs_and_moves_within_seconds() -> None:
    """The default getup composes its proof with the library motions' start proofs, as the guard
    does: a cold cache says so and fills it; a getup after it reads them and moves in seconds."""
    code, out = _run_cli("getup", "--mock", "--twin", "--lying", "prone", "--seed", "1")
    assert code == 0, out
    assert "library motions compose" in out and "standing after 1 attempt(s)" in out
    code, out = _run_cli("getup", "--mock", "--twin", "--lying", "supine", "--seed", "1", "--json")
    first = json.loads(out)["attempts"][0]
    assert code == 0 and first["proven"] and first["standing"]
    assert first["estimate_cpu_s"] + first["plan_cpu_s"] < 5.0  # whole proofs: 10-20 s here


def test_that_a_low_supply_refuses_to_move_and_leaves_the_robot_limp(robot: Robot) -> None:
    with _lying_session(robot, "supine") as (s, _):
        bus = mb.attached(s.io.connection.url.removeprefix("dxlsim://"))
        bus.faults.input_voltage_v = 10.2  # the servos still run; our 10.5 V floor refuses
        report = get_up(s.io, s.planner, s.estimator, truth=s.truth)
        limp = not any(servo.torque_on for servo in bus.servos.values())
    assert not report.standing and report.gave_up
    assert len(report.attempts) == 1 and report.attempts[0].health
    assert "10.2 V" in report.reason and "health check failed" in report.reason
    assert s.io.executions == [] and limp


# ---- the loop on a scripted robot (pure, no physics) ---------------------------------------------


@dataclass(frozen=True)
class _Sample:
    t_s: float
    angular_velocity_rad_s: tuple[float, float, float]
    specific_force_m_s2: tuple[float, float, float]
    valid: bool = True


@dataclass
class _ScriptedRobot:
    """A RobotIO whose IMU follows a script: upright, tipping forward at 3 rad/s, then lying prone."""

    robot: Robot
    hot_c: float = 40.0
    to_the_left: bool = False  # tip onto the left side instead of the front
    imu_dies_with_the_motion: bool = False  # no IMU sample after execute()
    t: float = 0.0
    calls: list[str] = field(default_factory=list)

    def now_s(self) -> float:
        return self.t

    def sleep(self, duration_s: float) -> None:
        self.t += duration_s

    def spent(self, compute_s: float) -> None:
        self.calls.append("spent")

    def read_joints(self) -> Mapping[str, float]:
        return dict(zip(self.robot.joint_names, self.robot.stand_qpos[7:]))

    def read_imu(self) -> _Sample:
        if self.imu_dies_with_the_motion and "execute" in self.calls:
            return _Sample(self.t, (math.nan,) * 3, (math.nan,) * 3, valid=False)  # type: ignore[arg-type]
        angle = min(math.pi / 2, max(0.0, (self.t - 1.0) * 3.0))
        moving = 1.0 <= self.t < 1.0 + math.pi / 6
        g, w = 9.80665, 3.0 if moving else 0.0
        if self.to_the_left:  # about -x: the left side goes down
            return _Sample(self.t, (-w, 0.0, 0.0), (0.0, -g * math.sin(angle), g * math.cos(angle)))
        return _Sample(self.t, (0.0, w, 0.0), (-g * math.sin(angle), 0.0, g * math.cos(angle)))

    def health(self) -> Health:
        return Health({j: self.hot_c for j in self.robot.joint_names}, {j: 12.0 for j in self.robot.joint_names})

    def execute(self, trajectory: object) -> ExecutionResult:
        self.calls.append("execute")
        return ExecutionResult(True, self.t, self.t)

    def go_limp(self) -> None:
        self.calls.append("limp")

    def hold(self) -> str:
        self.calls.append("hold")
        return ""


class _NeverPlans:
    def plan(self, estimate: object, attempt: int) -> PlannedGetUp:
        raise AssertionError("must not plan")


def test_that_the_guard_goes_limp_while_falling_and_an_overheated_robot_is_not_moved(robot: Robot) -> None:
    io_ = _ScriptedRobot(robot, hot_c=71.0)
    estimator = PostureEstimator(robot)
    state = GuardState(new_tracker())
    events = []
    while io_.t < 3.0:
        state, new = guard_step(io_, _NeverPlans(), estimator, state)
        events += new
        io_.sleep(0.01)
    kinds = [e.kind for e in events]
    assert kinds == [GuardEventKind.FALLING, GuardEventKind.GETUP]
    assert events[0].t_s < 1.3  # limp within 0.3 s of the tip starting, well before it lies
    report = events[1].report
    assert report is not None and report.gave_up and "71 degC" in report.reason
    assert "execute" not in io_.calls and io_.calls[-1] == "limp" and state.gave_up


@pytest.mark.parametrize("scheme", ["ours", "stock"])
def test_that_a_fall_onto_the_side_is_seen_by_ours_and_not_by_the_stock_pitch_test(robot: Robot, scheme: str) -> None:
    config = GetUpConfig() if scheme == "ours" else GetUpConfig(limp_when_falling=False, fallen_pitch_deg=60.0,
                                                                 execute_unproven=True)
    io_ = _ScriptedRobot(robot, hot_c=71.0, to_the_left=True)
    estimator = PostureEstimator(robot)
    state = GuardState(new_tracker())
    events = []
    while io_.t < 3.0:
        state, new = guard_step(io_, _NeverPlans(), estimator, state, config=config)
        events += new
        io_.sleep(0.01)
    assert state.tracker.state is FallState.FALLEN and state.tracker.estimate.lying == "left"
    if scheme == "ours":
        assert [e.kind for e in events] == [GuardEventKind.FALLING, GuardEventKind.GETUP]
    else:  # no limp while falling, and a robot on its side never reads fallen to the stock OP3
        assert events == [] and io_.calls == []


class _PlansAStillStand:
    def plan(self, estimate: PostureEstimate, attempt: int) -> PlannedGetUp:
        names = tuple(estimate.posture.joints)
        q = np.array([[estimate.posture.joints[j] for j in names]] * 2)
        return PlannedGetUp(Trajectory("op3", names, np.array([0.0, 1.0]), q, estimate.posture), True, motion="still")


def test_that_an_imu_lost_during_the_get_up_stops_trying_and_leaves_the_servos_holding(robot: Robot) -> None:
    io_ = _ScriptedRobot(robot, imu_dies_with_the_motion=True)
    fallen, _ = watch(io_, new_tracker(), until=(FallState.FALLEN,), timeout_s=5.0, cycle_s=0.01)
    report = get_up(io_, _PlansAStillStand(), PostureEstimator(robot), tracker=fallen)
    assert not report.standing and report.gave_up and len(report.attempts) == 1
    assert "the IMU stopped answering" in report.reason and "holding" in report.reason
    assert io_.calls.count("execute") == 1 and "limp" not in io_.calls  # blind: it may stand, do not drop it


def test_that_health_problems_name_each_servo_and_limit() -> None:
    h = Health({"r_knee": 66.0, "l_knee": 40.0}, {"r_knee": 12.0, "l_knee": 15.0}, {"head_pan": "overload"}, ("l_el",))
    problems = health_problems(h)
    assert problems == ("servo of l_el did not answer", "head_pan: hardware error (overload)",
                        "r_knee: 66 degC, above 65 degC", "l_knee: 15.0 V, outside 10.5..14.5 V")
    with pytest.raises(ValueError, match="attempts"):
        GetUpConfig(attempts=0)
    # a 4S robot (14.8 V) at full charge is fine; at 12 V its battery is flat
    four_cell = health_limits_for_supply(14.8)
    assert health_problems(Health({}, {"l_knee": 16.8}), four_cell) == ()
    assert health_problems(Health({}, {"l_knee": 12.0}), four_cell) == ("l_knee: 12.0 V, outside 13.0..17.9 V",)
    assert health_limits_for_supply(12.0) == HealthLimits()


# ---- the guard's pushes --------------------------------------------------------------------------


@pytest.mark.slow
def test_that_guard_pushes_the_twin_over_and_reports_each_push_in_json() -> None:
    code, out = _run_cli("guard", "--mock", "--twin", "--pushes", "2", "--seed", "0", "--json")
    result = json.loads(out)
    pushes = result["pushes"]
    assert len(pushes) == 2
    for p in pushes:
        assert PUSH_FIELDS <= set(p)
    toppled = [p for p in pushes if p["toppled"]]
    assert toppled, "pushes of 20-60 N topple the twin's OP3 most times"
    for p in toppled:
        assert p["lying"] in ("supine", "prone", "left", "right") and p["max_tilt_deg"] > 50
        assert p["standing"] and 1 <= p["attempts"] <= 3
        assert p["standing_after_s"] > p["first_command_after_s"] > 0
    assert result["summary"]["toppled"] == len(toppled) and code == 0
