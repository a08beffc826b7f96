"""Execution wiring shared by ``execute`` and ``demo``: a trajectory onto the servos (real bus,
emulator, or emulator moved by the physics twin) under the safety layer, printing as it goes.

This is the one place where the core (robot, trajectory, proof, twin) meets ``drivers`` (servo map,
preflight, executor); the commands only parse their options and call :func:`execute_trajectory`.

Executed = proven: a proof records the command limits it was proven under (report
``command_limits``); a trajectory proven under other limits than the executor's (rate, speed
limit, joint limits, or a ``--speed`` above 1) is refused. A proof's predicted positions (report
``predicted``) become the executor's expected positions: tracking is watched against them, with
the proof's per-joint tolerance, instead of against an absolute distance from the last command.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from robot_rise.errors import RobotRiseError
from robot_rise.filter.command_limits import (
    DEFAULT_RATE_HZ,
    CommandLimits,
    command_limits_of,
    match_command_limits,
)
from robot_rise.proof.prediction import expected_positions_of
from robot_rise.model import Robot
from robot_rise.trajectory import Trajectory

if TYPE_CHECKING:
    from drivers.safety import ExpectedPositions, SafetyLimits
    from drivers.servo_map import ServoMap

__all__ = ["ExecutionConfig", "execute_trajectory", "WATCHDOG_S"]

WATCHDOG_S = 0.1  # [s] Bus Watchdog armed while streaming: the servos stop if the host goes silent


@dataclass(frozen=True)
class ExecutionConfig:
    """How to execute: where (port or emulator, twin), how fast, with what stop policy and log.

    Attributes mirror ``robot-rise execute``'s options (rates in Hz, times in s).
    """

    port: str | None = None
    mock: bool = False
    twin: bool = False
    scene: str | None = None
    realtime: bool = False
    baud: int | None = None
    speed: float = 1.0
    approach: float | None = None
    rate: float = DEFAULT_RATE_HZ
    stop: str = "hold"
    allow_unproven: bool = False
    yes: bool = False
    log: str | None = None
    rt_priority: int | None = None
    cpu_idle: bool = False


def execute_trajectory(robot: Robot, traj: Trajectory, config: ExecutionConfig) -> int:
    """Check, preflight and stream ``traj`` to ``robot``'s servos; return the exit code.

    Returns:
        0 if the whole trajectory ran without a fault, 1 on a fault, 2 when refused at preflight
        or by the operator, 130 when interrupted.

    Raises:
        RobotRiseError: refused input (another robot's trajectory, not proven, outside the limits,
            an unwritable log) before anything moves.
    """
    import numpy as np

    from drivers.clock import FakeClock
    from drivers.errors import CommunicationError
    from drivers.executor import Executor, ExecutorConfig
    from drivers.safety import SafetyLimits, StopPolicy, check_limits, voltage_limits_for_supply
    from drivers.servo_map import load_servo_map
    from drivers.session import connect, mock_url_for
    from drivers.startup import disarm_watchdog, engage, preflight
    from drivers.startup1 import host_stop_guard
    from robot_rise.proof import execution_permit

    if traj.robot and traj.robot != robot.name:
        raise RobotRiseError(f"trajectory is for robot {traj.robot!r}, not {robot.name!r}",
                             hint="pass --robot DIR of the robot it was made for")
    if config.twin and not config.mock:
        raise RobotRiseError("--twin needs --mock (the twin moves emulated servos)")
    permit = execution_permit(traj.report, robot, traj)
    if not permit.allowed:
        if not config.allow_unproven:
            raise RobotRiseError(permit.reason, hint="run it through the dynamics filter, or pass --allow-unproven to run it anyway")
        print(f"warning: {permit.reason}; running anyway (--allow-unproven)", file=sys.stderr)
    else:
        scene = traj.report.get("scene")
        print(f"proven on robot {robot.name}" + (f" in scene {scene}" if scene else ""))
    smap = load_servo_map(robot.directory / "servos.toml")
    limits = SafetyLimits(smap.lower_rad, smap.upper_rad, **voltage_limits_for_supply(smap.bus.supply_voltage_v))
    expected = _proven_limits_and_expected(traj, smap, limits, config, proven=permit.allowed)
    lim = check_limits(np.asarray(traj.q)[:, smap.index_of(traj.joint_names)], limits)
    if not lim.ok:
        joint = smap.servos[lim.joint_index].joint
        raise RobotRiseError(
            f"trajectory leaves the joint limits: {joint} = {lim.value_rad:.3f} rad at t = "
            f"{float(traj.t[lim.sample_index]):.2f} s (limit {lim.limit_rad:.3f} rad, servos.toml)",
            hint="is it for this robot and in radians? check it with robot-rise check TRAJ")
    if config.log:  # fail before anything is powered, not after torque is on
        try:
            Path(config.log).open("w").close()
        except OSError as e:
            raise RobotRiseError(f"cannot write the log {config.log}: {e.strerror or e}") from e
    port = config.port
    twin = None
    clock = None
    if config.mock:
        if config.twin:
            from robot_rise.sim.twin import MujocoTwin

            scene = config.scene or traj.report.get("scene") or "flat"
            twin = MujocoTwin(robot, scene, start=traj.start)
            if not config.realtime:
                clock = FakeClock()
            print(f"physics twin: robot {robot.name} in scene {scene}; "
                  + ("wall clock" if config.realtime else "simulated clock (timing figures are not wall-clock)"))
            initial = dict(traj.start.joints)
        else:
            initial = dict(zip(traj.joint_names, np.asarray(traj.q)[0]))
        port = mock_url_for(smap, initial_rad=initial, plant=twin, clock=clock)
    executor_config = ExecutorConfig(rate_hz=config.rate, speed=config.speed, approach_s=config.approach,
                                     stop_policy=StopPolicy(config.stop),
                                     log_path=Path(config.log) if config.log else None,
                                     realtime_priority=config.rt_priority,
                                     cpu_latency_us=None if config.cpu_idle else 0, expected=expected)
    with connect(smap, port, baud_rate=config.baud) as conn:
        pre = preflight(conn.group)
        print(f"preflight: {len(pre.found)}/{len(smap)} servos, {len(pre.changes)} setting(s) changed, "
              f"{'fast' if pre.fast_read else 'plain'} sync read; {conn.latency.note}")
        if pre.hardware_errors:
            print(f"error: hardware errors at start: {pre.hardware_errors}", file=sys.stderr)
            print("hint: robot-rise servos reboot ID --port PORT", file=sys.stderr)
            return 2
        executor = Executor(conn.group, limits, executor_config)
        fb = conn.group.read_feedback()
        executor.prepare(traj.joint_names, traj.t, traj.q, fb.position_rad)  # refuses a far start
        duration = float(traj.t[-1] - traj.t[0]) / config.speed
        if not config.yes:
            try:
                answer = input(f"stream {duration:.1f} s of motion to {len(smap)} servos on {conn.url}? [y/N] ")
            except EOFError:  # no terminal to ask (a pipe, CI): the answer is no
                answer = ""
                print("\nno answer (stdin closed); pass --yes to run without asking")
            if answer.strip().lower() not in ("y", "yes"):
                print("aborted; nothing moved")
                return 2
        # a bus without a Bus Watchdog (Protocol 1.0): SIGTERM / SIGHUP stop by policy as Ctrl-C does,
        # and an error escaping the run turns torque off on the way out
        with host_stop_guard(conn.group):
            engage(conn.group, watchdog_s=WATCHDOG_S)
            try:
                rep = executor.run(traj.joint_names, traj.t, traj.q)
            finally:
                try:
                    disarm_watchdog(conn.group)
                except CommunicationError as e:  # keep the run's own outcome; the stop already ran
                    print(f"warning: could not disarm the Bus Watchdog: {e}", file=sys.stderr)
    s = rep.stats
    print(f"cycles {s.cycles} at {1 / s.period_s:.0f} Hz; jitter p50 {s.jitter_p50_s * 1e3:.3f} ms, "
          f"p99 {s.jitter_p99_s * 1e3:.3f} ms, max {s.jitter_max_s * 1e3:.3f} ms; "
          f"deadline misses {s.deadline_misses}; cycle work {s.work_mean_s * 1e3:.2f} ms mean"
          + (f"; {s.resyncs} stall(s) re-anchored the schedule (motion delayed)" if s.resyncs else ""))
    if clock is None:
        print(f"timing: {rep.timing}")
    print(f"max tracking error {rep.max_tracking_error_rad:.4f} rad; safety-clamped cycles {rep.clamped_cycles}")
    if rep.max_expected_error_rad is not None and rep.max_expected_ratio is not None:
        print(f"largest distance outside the band from the proof's predicted positions to the goals {rep.max_expected_error_rad:.4f} rad "
              f"({rep.max_expected_ratio:.2f} of its tolerance)")
    for f in rep.faults:
        joint = smap.servos[f.index].joint if 0 <= f.index < len(smap) else "bus"
        print(f"FAULT {f.kind.value} at {joint}: {f.message}")
    if rep.recovery is not None:
        for line in rep.recovery.messages:
            print(f"recovery: {line}")
    if rep.log_path:
        print(f"log: {rep.log_path}")
    if twin is not None:
        st = twin.state()
        print(f"twin: {st.t_s:.1f} s simulated; torso tilt {math.degrees(st.tilt_rad):.1f} deg, torso height "
              f"{st.torso_height_m:.3f} m (stand {st.stand_height_m:.3f} m): "
              + ("upright" if st.upright else "NOT upright"))
    print("completed" if rep.completed else f"stopped ({rep.stop_policy.value})")
    if rep.interrupted:
        return 130
    return 0 if rep.completed else 1


def _proven_limits_and_expected(traj: Trajectory, smap: ServoMap, limits: SafetyLimits, config: ExecutionConfig, *,
                                proven: bool) -> ExpectedPositions | None:
    """Refuse a trajectory proven under other command limits than these; return the proof's
    predicted positions as the executor's expected positions (map order), or None.

    A report without ``command_limits`` (a file from before they were recorded) runs as before,
    with a warning line; so does a mismatch under ``--allow-unproven``. The predicted positions
    are for the proven timing: at another ``--speed`` tracking is watched against the command.

    Raises:
        RobotRiseError: proven under other limits (one line and a hint), or a malformed entry.
    """
    from drivers.errors import DriverError
    from drivers.safety import ExpectedPositions

    proven_limits = command_limits_of(traj.report)
    if proven_limits is None:
        print("warning: the trajectory's report records no command limits (a file from before they were): "
              "the safety layer may clamp its targets", file=sys.stderr)
    else:
        executing = CommandLimits(smap.joint_names, smap.lower_rad, smap.upper_rad, limits.max_velocity_rad_s,
                                  config.rate)
        match = match_command_limits(proven_limits, executing, speed=config.speed)
        if not match.ok:
            if not config.allow_unproven:
                raise RobotRiseError(match.reason, hint=match.hint)
            print(f"warning: {match.reason}; running anyway (--allow-unproven)", file=sys.stderr)
    predicted = expected_positions_of(traj.report) if proven else None
    if predicted is None:
        return None
    if config.speed != 1.0:
        print(f"note: tracking watched against the command ({limits.max_tracking_error_rad} rad), not the proof's "
              f"predicted positions: they are for --speed 1")
        return None
    try:
        idx = smap.index_of(predicted.joint_names)
    except DriverError as e:
        raise RobotRiseError(f"the proof's predicted positions do not fit the servo map: {e}",
                             hint="is it for this robot? (servos.toml)") from None
    tol = predicted.tolerance_rad[idx]
    print(f"tracking watched against the band from the proof's predicted positions to the goals (tolerance {tol.min():.3f}.."
          f"{tol.max():.3f} rad)")
    return ExpectedPositions(predicted.t_s, predicted.q_rad[:, idx], tol)
