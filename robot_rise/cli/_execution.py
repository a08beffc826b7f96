"""Execution wiring shared by ``execute`` and ``demo``: a trajectory onto the servos (real bus,
emulator, or emulator moved by the physics twin) under the safety layer.

This is the one place where the core (robot, trajectory, proof, twin) meets ``drivers`` (servo map,
preflight, executor); the commands only parse their options, call :func:`execute_trajectory` and
print its :class:`ExecutionResult` as text (:func:`result_lines`) or JSON (``as_dict``). What
happens before the motion (the permit, the preflight, the prompt) is written to a progress stream
as it happens: stdout for text, stderr under ``--json``; warnings go to stderr.

Executed = proven: a proof records the command limits it was proven under (report
``command_limits``); a trajectory proven under other limits than the executor's (rate, speed
limit, joint limits, or a ``--speed`` above 1) is refused. A proof's predicted positions (report
``predicted``) become the executor's expected positions: tracking is watched against them, with
the proof's per-joint tolerance, instead of against an absolute distance from the last command.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

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

__all__ = ["ExecutionConfig", "ExecutionResult", "ExecutedFault", "TwinVerdict", "execute_trajectory",
           "result_lines", "WATCHDOG_S"]

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


@dataclass(frozen=True)
class ExecutedFault:
    """One fault that stopped the run: ``kind`` (drivers' FaultKind value), the joint (``bus`` for
    the whole bus), the measured ``value`` and the ``limit`` it crossed (rad, degC, V, count ...)."""

    kind: str
    joint: str
    value: float
    limit: float
    message: str


@dataclass(frozen=True)
class TwinVerdict:
    """The physics twin at the end of the run: simulated time [s], torso tilt [rad], torso height
    above the soles and the same in the stand keyframe [m], upright by the standing thresholds."""

    simulated_s: float
    tilt_rad: float
    torso_height_m: float
    stand_height_m: float
    upright: bool


@dataclass(frozen=True)
class ExecutionResult:
    """What one ``execute`` did (the facts its text prints).

    Attributes:
        exit_code: 0 ran without a fault, 1 on a fault, 2 refused at preflight or by the operator,
            130 interrupted.
        robot: the robot's name.
        proven: the execution permit allowed it (False only under ``--allow-unproven``).
        permit_reason: why the permit refused ("" when proven).
        scene: the scene the proof names (None: none named).
        tracking_band_rad: (min, max) per-joint tolerance [rad] of the band from the proof's
            predicted positions to the goals; None: tracking watched against the command.
        servos_found / servos_total: servos that answered at preflight, servos in the map.
        not_run: why nothing moved ("" when it ran).
        completed: the whole trajectory ran without a fault.
        stop_policy: the stop policy applied at the end (``hold`` / ``limp``).
        cycles, rate_hz, jitter_*_s, deadline_misses, work_mean_s, resyncs: the loop's timing
            (simulated on the twin's clock).
        timing: how the loop ran on the wall clock (None on a simulated clock).
        max_tracking_error_rad: largest |present - previous command| [rad] (None: did not run).
        clamped_cycles: cycles in which the safety layer changed the target.
        max_band_error_rad: largest distance outside the tracking band [rad] (None: not watched).
        band_used: that distance / the tolerance, largest seen (None: not watched).
        faults: the faults that stopped it.
        recovery: the recovery's lines, if one was attempted.
        log_path: the per-cycle CSV log, if written.
        twin: the twin's state at the end (None without ``--twin``).
    """

    exit_code: int
    robot: str
    proven: bool
    permit_reason: str = ""
    scene: str | None = None
    tracking_band_rad: tuple[float, float] | None = None
    servos_found: int = 0
    servos_total: int = 0
    not_run: str = ""
    completed: bool = False
    stop_policy: str = "hold"
    cycles: int = 0
    rate_hz: float = 0.0
    jitter_p50_s: float = 0.0
    jitter_p99_s: float = 0.0
    jitter_max_s: float = 0.0
    deadline_misses: int = 0
    work_mean_s: float = 0.0
    resyncs: int = 0
    timing: str | None = None
    max_tracking_error_rad: float | None = None
    clamped_cycles: int = 0
    max_band_error_rad: float | None = None
    band_used: float | None = None
    faults: tuple[ExecutedFault, ...] = ()
    recovery: tuple[str, ...] = ()
    log_path: str | None = None
    twin: TwinVerdict | None = None

    def as_dict(self) -> dict[str, Any]:
        """The result as JSON-ready values (faults and the twin as objects)."""
        d = asdict(self)
        d["tracking_band_rad"] = list(self.tracking_band_rad) if self.tracking_band_rad else None
        d["faults"] = [asdict(f) for f in self.faults]
        d["recovery"] = list(self.recovery)
        return d


def result_lines(result: ExecutionResult) -> list[str]:
    """The lines ``execute`` prints after the motion (none when nothing moved)."""
    r = result
    if r.not_run:
        return []
    lines = [f"cycles {r.cycles} at {r.rate_hz:.0f} Hz; jitter p50 {r.jitter_p50_s * 1e3:.3f} ms, "
             f"p99 {r.jitter_p99_s * 1e3:.3f} ms, max {r.jitter_max_s * 1e3:.3f} ms; "
             f"deadline misses {r.deadline_misses}; cycle work {r.work_mean_s * 1e3:.2f} ms mean"
             + (f"; {r.resyncs} stall(s) re-anchored the schedule (motion delayed)" if r.resyncs else "")]
    if r.timing is not None:
        lines.append(f"timing: {r.timing}")
    lines.append(f"max tracking error {r.max_tracking_error_rad:.4f} rad; safety-clamped cycles {r.clamped_cycles}")
    if r.max_band_error_rad is not None and r.band_used is not None:
        lines.append(f"largest distance outside the band from the proof's predicted positions to the goals "
                     f"{r.max_band_error_rad:.4f} rad ({r.band_used:.2f} of its tolerance)")
    lines += [f"FAULT {f.kind} at {f.joint}: {f.message}" for f in r.faults]
    lines += [f"recovery: {line}" for line in r.recovery]
    if r.log_path:
        lines.append(f"log: {r.log_path}")
    if r.twin is not None:
        tw = r.twin
        lines.append(f"twin: {tw.simulated_s:.1f} s simulated; torso tilt {math.degrees(tw.tilt_rad):.1f} deg, torso height "
                     f"{tw.torso_height_m:.3f} m (stand {tw.stand_height_m:.3f} m): "
                     + ("upright" if tw.upright else "NOT upright"))
    lines.append("completed" if r.completed else f"stopped ({r.stop_policy})")
    return lines


def execute_trajectory(robot: Robot, traj: Trajectory, config: ExecutionConfig, *,
                       progress: TextIO | None = None) -> ExecutionResult:
    """Check, preflight and stream ``traj`` to ``robot``'s servos; return what happened.

    Args:
        progress: where the lines before the motion go as they happen (permit, twin, preflight,
            prompt); default stdout. Warnings and errors go to stderr.

    Returns:
        The :class:`ExecutionResult`; its ``exit_code`` is 0 if the whole trajectory ran without
        a fault, 1 on a fault, 2 when refused at preflight or by the operator, 130 when interrupted.

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

    out = progress if progress is not None else sys.stdout

    def say(line: str) -> None:
        print(line, file=out, flush=True)

    if traj.robot and traj.robot != robot.name:
        raise RobotRiseError(f"trajectory is for robot {traj.robot!r}, not {robot.name!r}",
                             hint="pass --robot DIR of the robot it was made for")
    if config.twin and not config.mock:
        raise RobotRiseError("--twin needs --mock (the twin moves emulated servos)")
    permit = execution_permit(traj.report, robot, traj)
    proof_scene = traj.report.get("scene")
    if not permit.allowed:
        if not config.allow_unproven:
            raise RobotRiseError(permit.reason, hint="run it through the dynamics filter, or pass --allow-unproven to run it anyway")
        print(f"warning: {permit.reason}; running anyway (--allow-unproven)", file=sys.stderr)
    else:
        say(f"proven on robot {robot.name}" + (f" in scene {proof_scene}" if proof_scene else ""))
    smap = load_servo_map(robot.directory / "servos.toml")
    limits = SafetyLimits(smap.lower_rad, smap.upper_rad, **voltage_limits_for_supply(smap.bus.supply_voltage_v))
    expected = _proven_limits_and_expected(traj, smap, limits, config, proven=permit.allowed, say=say)
    band = (float(expected.tolerance_rad.min()), float(expected.tolerance_rad.max())) if expected is not None else None
    facts: dict[str, Any] = dict(robot=robot.name, proven=permit.allowed, permit_reason="" if permit.allowed else permit.reason,
                                 scene=proof_scene, tracking_band_rad=band, servos_total=len(smap))
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
            say(f"physics twin: robot {robot.name} in scene {scene}; "
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
        facts["servos_found"] = len(pre.found)
        say(f"preflight: {len(pre.found)}/{len(smap)} servos, {len(pre.changes)} setting(s) changed, "
              f"{'fast' if pre.fast_read else 'plain'} sync read; {conn.latency.note}")
        if pre.hardware_errors:
            print(f"error: hardware errors at start: {pre.hardware_errors}", file=sys.stderr)
            print("hint: robot-rise servos reboot ID --port PORT", file=sys.stderr)
            return ExecutionResult(2, **facts, not_run=f"hardware errors at start: {pre.hardware_errors}")
        executor = Executor(conn.group, limits, executor_config)
        fb = conn.group.read_feedback()
        executor.prepare(traj.joint_names, traj.t, traj.q, fb.position_rad)  # refuses a far start
        duration = float(traj.t[-1] - traj.t[0]) / config.speed
        if not config.yes:
            question = f"stream {duration:.1f} s of motion to {len(smap)} servos on {conn.url}? [y/N] "
            try:
                if out is sys.stdout:
                    answer = input(question)
                else:  # the question goes where the progress goes (stderr under --json)
                    print(question, end="", file=out, flush=True)
                    answer = input("")
            except EOFError:  # no terminal to ask (a pipe, CI): the answer is no
                answer = ""
                say("\nno answer (stdin closed); pass --yes to run without asking")
            if answer.strip().lower() not in ("y", "yes"):
                say("aborted; nothing moved")
                return ExecutionResult(2, **facts, not_run="aborted at the prompt")
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
    twin_verdict = None
    if twin is not None:
        st = twin.state()
        twin_verdict = TwinVerdict(st.t_s, st.tilt_rad, st.torso_height_m, st.stand_height_m, st.upright)
    faults = tuple(ExecutedFault(f.kind.value, smap.servos[f.index].joint if 0 <= f.index < len(smap) else "bus",
                                 f.value, f.limit, f.message) for f in rep.faults)
    code = 130 if rep.interrupted else 0 if rep.completed else 1
    return ExecutionResult(
        code, **facts, completed=rep.completed, stop_policy=rep.stop_policy.value,
        cycles=s.cycles, rate_hz=1 / s.period_s, jitter_p50_s=s.jitter_p50_s, jitter_p99_s=s.jitter_p99_s,
        jitter_max_s=s.jitter_max_s, deadline_misses=s.deadline_misses, work_mean_s=s.work_mean_s, resyncs=s.resyncs,
        timing=rep.timing if clock is None else None, max_tracking_error_rad=rep.max_tracking_error_rad,
        clamped_cycles=rep.clamped_cycles, max_band_error_rad=rep.max_expected_error_rad, band_used=rep.max_expected_ratio,
        faults=faults, recovery=tuple(rep.recovery.messages) if rep.recovery is not None else (),
        log_path=str(rep.log_path) if rep.log_path else None, twin=twin_verdict)


def _proven_limits_and_expected(traj: Trajectory, smap: ServoMap, limits: SafetyLimits, config: ExecutionConfig, *,
                                proven: bool, say: Callable[[str], None]) -> ExpectedPositions | None:
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
        say(f"note: tracking watched against the command ({limits.max_tracking_error_rad} rad), not the proof's "
              f"predicted positions: they are for --speed 1")
        return None
    try:
        idx = smap.index_of(predicted.joint_names)
    except DriverError as e:
        raise RobotRiseError(f"the proof's predicted positions do not fit the servo map: {e}",
                             hint="is it for this robot? (servos.toml)") from None
    tol = predicted.tolerance_rad[idx]
    say(f"tracking watched against the band from the proof's predicted positions to the goals (tolerance {tol.min():.3f}.."
          f"{tol.max():.3f} rad)")
    return ExpectedPositions(predicted.t_s, predicted.q_rad[:, idx], tol)
