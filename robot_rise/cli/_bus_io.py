"""The live loop's robot over ``drivers``: :class:`BusRobotIO`, the ``robot_rise.live.io.RobotIO``
of one bus (the servo group and the OpenCR IMU; a real port, or the emulated bus, optionally moved
by the physics twin).

It lives in ``cli/`` because it imports both sides: the core (``robot_rise.live``, the proof's
permit and prediction) never imports ``drivers``, and ``cli/`` is the room that wires the core to
``drivers`` (as :mod:`robot_rise.cli._execution` does for ``execute``). ``getup`` and ``guard``
open it through ``robot_rise.cli.cmd_getup.open_live_session``.
"""

from __future__ import annotations

import math
import sys
from typing import TYPE_CHECKING, Any

from robot_rise.cli._execution import WATCHDOG_S
from robot_rise.errors import RobotRiseError

if TYPE_CHECKING:
    from drivers.imu import ImuSample, OpenCrImu
    from drivers.servo_map import ServoMap
    from drivers.session import Connection
    from robot_rise.live.health import Health
    from robot_rise.live.io import ExecutionResult
    from robot_rise.model import Robot
    from robot_rise.posture import Posture
    from robot_rise.sim.twin import MujocoTwin
    from robot_rise.trajectory import Trajectory

__all__ = ["BusRobotIO"]


class BusRobotIO:
    """``robot_rise.live.io.RobotIO`` over one bus: the servo group and the OpenCR IMU.

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
        from robot_rise.live.health import Health

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
        from robot_rise.proof import execution_permit
        from robot_rise.live.io import ExecutionResult

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
        from robot_rise.proof import execution_permit
        from robot_rise.filter.command_limits import CommandLimits, command_limits_of, match_command_limits
        from robot_rise.proof.prediction import expected_positions_of
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
