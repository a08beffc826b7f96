"""robot-rise getup: one shot from the present state: estimate, plan, prove, execute, confirm, retry.

Also the wiring ``getup`` and ``guard`` share (:func:`open_live_session`): the robot as
``robot_rise.live.getup.RobotIO`` over ``drivers`` (the servo group and the OpenCR IMU on one bus,
a real port or the emulated bus, optionally moved by the physics twin).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import math
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from robot_rise.cli._common import Formatter, print_json
from robot_rise.errors import RobotRiseError

if TYPE_CHECKING:
    from drivers.imu import ImuSample, OpenCrImu
    from drivers.servo_map import ServoMap
    from drivers.session import Connection
    from robot_rise.live.estimate import PostureEstimator
    from robot_rise.live.getup import ExecutionResult, GetUpConfig, Health, KeyframePlanner, RisePlanner
    from robot_rise.model import Robot
    from robot_rise.posture import Posture
    from robot_rise.sim.twin import MujocoTwin
    from robot_rise.trajectory import Trajectory

EPILOG = """examples:
  robot-rise getup --port /dev/ttyUSB0                      # the robot on the floor gets up
  robot-rise getup --mock --twin --lying prone --seed 3     # the simulated robot, lying prone
  robot-rise getup --mock --twin --start lying.json --attempts 2 --json
The robot's IMU is read through the OpenCR sub-controller (ID 200) on the servo bus. Before each
try the servos' temperatures and voltage are checked; a failing check, or no success after
--attempts tries, leaves the robot limp. With --twin the clock is simulated: thinking time (CPU)
is let pass on it, so the times reported include it.
exit code: 0 standing at the end; 1 not standing (gave up, limp); 2 refused input.
"""

STOCK_PITCH_DEG = 60.0  # [deg] the stock OP3's fall test: torso pitch past 60 deg, front or back
WATCHDOG_S = 0.1  # [s] Bus Watchdog while a get-up streams (the executor's, as robot-rise execute)
# the twin's OpenCR: the sensor errors of sim_tests/test_fall_detection.py (noise, bias per axis)
IMU_NOISE = {"gyro_noise_rad_s": 0.01, "accel_noise_m_s2": 0.05, "gyro_bias_rad_s": (0.02, -0.01, 0.01),
             "accel_bias_m_s2": (0.1, -0.1, 0.05), "orientation_noise_rad": 0.005}


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("getup", help="get the robot up from where it lies: estimate, plan, prove, execute, check, retry",
                       formatter_class=Formatter, epilog=EPILOG)
    add_live_args(p)
    p.add_argument("--attempts", type=int, default=3, help="tries at most before giving up (default 3)")
    p.add_argument("--lying", choices=["supine", "prone", "left", "right"],
                   help="with --twin: start the twin lying like this (a settled random posture, --seed)")
    p.add_argument("--start", metavar="POSTURE", help="with --twin: start the twin in this posture file")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.set_defaults(func=run)


def add_live_args(p: argparse.ArgumentParser) -> None:
    """Options ``getup`` and ``guard`` share."""
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--port", help="serial device or pyserial URL of the servo bus (with the OpenCR at ID 200)")
    g.add_argument("--mock", action="store_true", help="emulated bus with an emulated OpenCR")
    p.add_argument("--twin", action="store_true", help="with --mock: the servos and the IMU are a MuJoCo simulation of the robot")
    p.add_argument("--robot", metavar="DIR", help="robot directory (default: the embedded OP3)")
    p.add_argument("--scene", default="flat", help="scene the robot is in (default: flat)")
    p.add_argument("--baud", type=int, help="baud rate [bit/s] (default: from servos.toml)")
    p.add_argument("--seed", type=int, default=0, help="seed of the twin's start posture, IMU noise and pushes (default 0)")
    p.add_argument("--budget", type=float, default=5.0, help="planning budget per candidate motion [s] (default 5)")
    p.add_argument("--scheme", choices=["ours", "stock"], default="ours",
                   help="ours: falls in every direction, limp while falling, proven get-ups (default); stock: "
                        "the stock OP3's scheme for comparison (fallen when the pitch passes 60 deg, front or "
                        "back keyframe get-up, not proven, no limp)")


def scheme_config(scheme: str, config: GetUpConfig) -> GetUpConfig:
    """``config`` for ``--scheme``: ours as it is; the stock OP3's fall test and keyframes."""
    if scheme == "stock":
        return dataclasses.replace(config, limp_when_falling=False, fallen_pitch_deg=STOCK_PITCH_DEG,
                                   execute_unproven=True)
    return config


# ---- the robot over drivers --------------------------------------------------------------------


class BusRobotIO:
    """``robot_rise.live.getup.RobotIO`` over one bus: the servo group and the OpenCR IMU.

    Args:
        robot: the robot model (its proofs are checked against it before streaming).
        servo_map: the servos.
        connection: the open bus (preflighted).
        imu: the IMU on that bus.
        simulated: the bus clock is simulated (``spent`` lets thinking time pass on it).
        twin: the physics twin moving the emulated servos (the truth), if any.
        allow_unproven: stream unproven trajectories too, without a tracking limit (the stock
            OP3 scheme's keyframes, for comparison; the stock OP3 watches no tracking error).
    """

    def __init__(self, robot: Robot, servo_map: ServoMap, connection: Connection, imu: OpenCrImu, *,
                 simulated: bool = False, twin: MujocoTwin | None = None, allow_unproven: bool = False) -> None:
        from drivers.safety import SafetyLimits, voltage_limits_for_supply

        self.robot = robot
        self.map = servo_map
        self.connection = connection
        self.group = connection.group
        self.clock = connection.bus.clock
        self.imu = imu
        self.simulated = simulated
        self.twin = twin
        volts = voltage_limits_for_supply(servo_map.bus.supply_voltage_v)
        self.limits = SafetyLimits(servo_map.lower_rad, servo_map.upper_rad, **volts)
        self.allow_unproven = allow_unproven
        self.unproven_limits = SafetyLimits(servo_map.lower_rad, servo_map.upper_rad, max_tracking_error_rad=math.pi, **volts)
        self.executions: list[Any] = []  # the executor's reports, in order

    # clock
    def now_s(self) -> float:
        return float(self.clock.now())

    def sleep(self, duration_s: float) -> None:
        self.clock.sleep(duration_s)

    def spent(self, compute_s: float) -> None:
        if self.simulated and compute_s > 0:
            self.clock.sleep(compute_s)

    # sensing
    def read_joints(self) -> dict[str, float]:
        fb = self.group.read_feedback()
        return {s.joint: float(q) for s, q, ok in zip(self.map.servos, fb.position_rad, fb.valid) if ok}

    def read_imu(self) -> ImuSample:
        return self.imu.read()

    def health(self) -> Health:
        from drivers.control_table import HardwareErrorBits
        from robot_rise.live.getup import Health

        fb = self.group.read_feedback()
        servos = self.map.servos
        ok = [k for k in range(len(servos)) if fb.valid[k]]
        return Health(
            temperatures_c={servos[k].joint: float(fb.temperature_c[k]) for k in ok},
            voltages_v={servos[k].joint: float(fb.voltage_v[k]) for k in ok},
            hardware_errors={servos[k].joint: HardwareErrorBits.describe(int(fb.alert[k])) for k in ok if fb.alert[k]},
            missing=tuple(servos[k].joint for k in range(len(servos)) if not fb.valid[k]),
        )

    def true_posture(self) -> Posture:
        if self.twin is None:
            raise RobotRiseError("no twin: the true posture is unknown")
        return self.twin.posture()

    # acting
    def execute(self, trajectory: Trajectory) -> ExecutionResult:
        from drivers.errors import DriverError
        from drivers.executor import Executor, ExecutorConfig
        from drivers.safety import FaultKind, StopPolicy
        from drivers.startup import engage
        from robot_rise.filter import execution_permit
        from robot_rise.live.getup import ExecutionResult

        limits = self.limits
        try:
            if self.allow_unproven and not execution_permit(trajectory.report, self.robot, trajectory).allowed:
                expected, tilt, limits = None, None, self.unproven_limits
            else:
                expected, tilt = self._permit(trajectory)
            engage(self.group, watchdog_s=WATCHDOG_S)
        except (DriverError, RobotRiseError) as e:
            return ExecutionResult(False, None, self.now_s(), f"refused: {e}")
        # no automatic reboot of a servo that shut down on a hardware error: rebooting clears the
        # error, and the health check before the next try is what must see it (and refuse)
        # the IMU is read in every cycle: a torso off the proof's tilt is a fall, not a get-up
        config = ExecutorConfig(stop_policy=StopPolicy.HOLD, expected=expected, recovery_attempts=0,
                                cpu_latency_us=None if self.simulated else 0, imu=self.imu, expected_tilt=tilt)
        first = self.now_s()
        try:
            rep = Executor(self.group, limits, config).run(trajectory.joint_names, trajectory.t, trajectory.q)
        except DriverError as e:  # refused before anything moved (a far start)
            self._disarm()
            return ExecutionResult(False, None, self.now_s(), f"refused: {e}")
        self._disarm()
        self.executions.append(rep)
        if any(f.kind is FaultKind.FALLING for f in rep.faults):
            self.go_limp()  # falling: servos that hold would fight the impact
        reason = "; ".join(f"{f.kind.value} at {self._fault_site(f)}: "
                           f"{f.message.removeprefix(f'joint {f.index}: ')}" for f in rep.faults)
        servos = self.map.servos
        lagging = tuple(dict.fromkeys(servos[f.index].joint for f in rep.faults
                                      if f.kind is FaultKind.TRACKING and 0 <= f.index < len(servos)))
        return ExecutionResult(rep.completed, first, self.now_s(), reason, rep.interrupted, lagging)

    def _fault_site(self, fault: Any) -> str:
        """Which servo an executor fault is about (its index is in map order; -1: the bus, or
        the IMU for a fall)."""
        from drivers.safety import FaultKind

        servos = self.map.servos
        if fault.kind is FaultKind.FALLING:
            return f"the IMU (id {self.imu.device_id})"
        return servos[fault.index].label if 0 <= fault.index < len(servos) else "the bus"

    def _disarm(self) -> None:
        from drivers.errors import CommunicationError
        from drivers.startup import disarm_watchdog

        try:
            disarm_watchdog(self.group)
        except CommunicationError as e:
            print(f"warning: could not disarm the Bus Watchdog: {e}", file=sys.stderr)

    def _permit(self, trajectory: Trajectory):
        """Executed = proven (as robot-rise execute): the proof is this robot's, under these
        command limits; returns the proof's predicted positions and torso tilt as the executor's
        expected ones (None where the proof has none)."""
        from drivers.safety import ExpectedPositions, ExpectedTilt
        from robot_rise.filter import execution_permit
        from robot_rise.filter.command_limits import CommandLimits, command_limits_of, match_command_limits
        from robot_rise.filter.prediction import expected_positions_of
        from drivers.executor import DEFAULT_RATE_HZ

        permit = execution_permit(trajectory.report, self.robot, trajectory)
        if not permit.allowed:
            raise RobotRiseError(permit.reason)
        proven_limits = command_limits_of(trajectory.report)
        if proven_limits is not None:
            executing = CommandLimits(self.map.joint_names, self.map.lower_rad, self.map.upper_rad,
                                      self.limits.max_velocity_rad_s, DEFAULT_RATE_HZ)
            match = match_command_limits(proven_limits, executing, speed=1.0)
            if not match.ok:
                raise RobotRiseError(match.reason, hint=match.hint)
        predicted = expected_positions_of(trajectory.report)
        if predicted is None:
            return None, None
        idx = self.map.index_of(predicted.joint_names)
        tilt = None if predicted.tilt_rad is None else ExpectedTilt(predicted.t_s, predicted.tilt_rad, predicted.tilt_tolerance_rad)
        return ExpectedPositions(predicted.t_s, predicted.q_rad[:, idx], predicted.tolerance_rad[idx]), tilt

    def go_limp(self) -> None:
        from drivers.errors import CommunicationError

        try:
            self.group.torque(False, quarantined_too=True)
        except CommunicationError as e:  # the servos' own watchdog and the next try still stand
            print(f"warning: torque off failed: {e}", file=sys.stderr)

    def hold(self) -> str:
        from drivers.errors import DriverError
        from drivers.startup import engage

        try:
            engage(self.group, watchdog_s=None)
        except DriverError as e:  # a joint past its limit, a silent servo: say why, do not move
            return str(e)
        return ""


@dataclass
class LiveSession:
    """What ``getup`` and ``guard`` run on: the robot IO, the planner, the estimator, the twin."""

    robot: Robot
    io: BusRobotIO
    planner: RisePlanner | KeyframePlanner
    estimator: PostureEstimator
    twin: MujocoTwin | None
    setup_s: float

    @property
    def truth(self) -> BusRobotIO | None:
        return self.io if self.twin is not None else None


@contextlib.contextmanager
def open_live_session(args: argparse.Namespace, *, start: Posture | None = None,
                      stock: bool = False, composed: bool = False,
                      say: Callable[[str], None] | None = None) -> Iterator[LiveSession]:
    """Connect (real bus, or the emulated bus with the OpenCR and, with --twin, the physics twin
    on a simulated clock), preflight, find the IMU; precompute the per-robot parts (rise context
    with the ensemble's players, the posture estimator). ``stock``: the stock OP3's keyframe
    planner instead (comparison). ``composed``: proofs composed with the library motions' start
    proofs (``robot_rise.filter.composed``), all precomputed here (a guard waits for falls; a
    one-shot get-up would spend more on them than they save)."""
    from drivers.clock import FakeClock
    from drivers.imu import OpenCrImu
    from drivers.mockbus.emulated_imu import EmulatedImu
    from drivers.mockbus.plant import ImuNoise
    from drivers.servo_map import load_servo_map
    from drivers.session import connect, mock_url_for
    from drivers.startup import preflight
    from robot_rise.live.estimate import PostureEstimator
    from robot_rise.live.getup import KeyframePlanner, RisePlanner
    from robot_rise.model import load_robot
    from robot_rise.posture import stand_posture
    from robot_rise.rise import RiseContext

    if args.twin and not args.mock:
        raise RobotRiseError("--twin needs --mock (the twin moves emulated servos)")
    t0 = time.monotonic()
    robot = load_robot(args.robot)
    smap = load_servo_map(robot.directory / "servos.toml")
    twin = None
    port = args.port
    if args.mock:
        start = start or stand_posture(robot)
        clock = None
        if args.twin:
            from robot_rise.sim.twin import MujocoTwin

            twin = MujocoTwin(robot, args.scene, start=start)
            clock = FakeClock()
        imu = EmulatedImu(noise=ImuNoise(**IMU_NOISE, seed=args.seed))  # type: ignore[arg-type]
        port = mock_url_for(smap, initial_rad=dict(start.joints), plant=twin, clock=clock, imu=imu)
    conn = connect(smap, port, baud_rate=args.baud)
    try:
        pre = preflight(conn.group)
        if pre.hardware_errors:
            raise RobotRiseError(f"hardware errors at start: {pre.hardware_errors}",
                                 hint="robot-rise servos reboot ID --port PORT")
        imu_dev = OpenCrImu(conn.bus)
        probe = imu_dev.probe()
        if not probe.ok:
            raise RobotRiseError(f"no IMU: {probe.message}",
                                 hint="the OP3's OpenCR sub-controller answers at ID 200 on the servo bus")
        context = RiseContext.build(robot, args.scene)
        planner: RisePlanner | KeyframePlanner
        if stock:
            planner = KeyframePlanner(robot, context.library)
        else:
            context.ensemble()  # the variants' players, built now rather than at the first fall
            if composed:
                t_warm = time.monotonic()
                (say or (lambda s: None))(f"proving the {len(context.library.motions)} library motions from rest on every model variant (once per start)")
                ready = context.warm_start_proofs()
                (say or (lambda s: None))(f"{ready} of {len(context.library.motions)} compose ({time.monotonic() - t_warm:.0f} s)")
            planner = RisePlanner(context, budget_s=args.budget, composed=composed)
        estimator = PostureEstimator(robot, args.scene, checker=context.checker)
        io = BusRobotIO(robot, smap, conn, imu_dev, simulated=twin is not None, twin=twin, allow_unproven=stock)
        yield LiveSession(robot, io, planner, estimator, twin, time.monotonic() - t0)
    finally:
        conn.close()


def _start_posture(args: argparse.Namespace, robot_dir: str | None) -> Posture | None:
    if not (args.lying or args.start):
        return None
    if not args.twin:
        raise RobotRiseError("--lying and --start set the twin's start: they need --mock --twin")
    if args.lying and args.start:
        raise RobotRiseError("--lying and --start both set the start: give one")
    from robot_rise.model import load_robot
    from robot_rise.posture import read_posture
    from robot_rise.sampling import sample_lying_postures

    robot = load_robot(robot_dir)
    if args.start:
        return read_posture(args.start, robot)
    return sample_lying_postures(robot, args.lying, 1, seed=args.seed, scene=args.scene)[0]


def _fmt(v: float | None, unit: str = "s") -> str:
    return "-" if v is None or not math.isfinite(v) else f"{v:.2f} {unit}"


def print_getup_report(report: Any, *, t_origin: float = 0.0) -> None:
    """One line per attempt, then the outcome."""
    for a in report.attempts:
        est = a.estimate
        err = ""
        if est is not None and est.error is not None:
            err = f", estimate off by {est.error.orientation_deg:.1f} deg / {est.error.root_height_m * 1000:+.0f} mm"
        print(f"attempt {a.attempt}: lying {a.lying or '-'}{err}; think {a.estimate_cpu_s + a.plan_cpu_s:.2f} s CPU; "
              + (f"{a.motion} proven" if a.proven else "not proven")
              + (f"; first command {_fmt(a.first_command_after_s)} after fallen-and-still" if a.first_command_s is not None else "")
              + ("; standing at " + _fmt(a.standing_s - t_origin) if a.standing and a.standing_s is not None else
                 f"; not standing: {a.why}"))
    if report.already_standing:
        print("standing already: nothing to do")
    elif report.standing:
        print(f"standing after {len(report.attempts)} attempt(s)")
    else:
        print(f"gave up, servos limp: {report.reason}" if report.gave_up else f"stopped: {report.reason}")


def run(args: argparse.Namespace) -> int:
    from robot_rise.live.getup import GetUpConfig, get_up, health_limits_for_supply

    if args.attempts < 1:
        raise RobotRiseError(f"--attempts {args.attempts}: at least 1")
    start = _start_posture(args, args.robot)
    config = scheme_config(args.scheme, GetUpConfig(attempts=args.attempts))
    with open_live_session(args, start=start, stock=args.scheme == "stock") as s:
        config = dataclasses.replace(config, health=health_limits_for_supply(s.io.map.bus.supply_voltage_v))
        if not args.json:
            print(f"robot {s.robot.name} on {s.io.connection.url}: {len(s.io.map)} servos and the IMU answer; "
                  f"ready in {s.setup_s:.1f} s" + ("; physics twin on a simulated clock" if s.twin else ""))
        t0 = s.io.now_s()
        report = get_up(s.io, s.planner, s.estimator, config=config, truth=s.truth)
        if args.json:
            print_json({"robot": s.robot.name, "scheme": args.scheme, "t0_s": t0, **report.to_dict()})
        else:
            print_getup_report(report, t_origin=t0)
    if report.interrupted:
        return 130
    return 0 if report.standing else 1
