"""robot-rise execute: stream a trajectory file to the servos (real bus or emulator) safely."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from pathlib import Path

from robot_rise.cli._common import Formatter
from robot_rise.errors import RobotRiseError

EPILOG = """examples:
  robot-rise execute out/demo/getup.json --mock --yes
  robot-rise execute out/demo/getup.json --mock --twin --yes   # does the simulated robot stand up?
  robot-rise execute getup.json --port /dev/ttyUSB0 --speed 0.5 --approach 3 --log run.csv
exit code: 0 only if the whole trajectory ran without a fault; 1 on a fault; 2 on refused input.
"""
WATCHDOG_S = 0.1  # [s] Bus Watchdog armed while streaming: the servos stop if the host goes silent


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("execute", help="preflight, then stream a trajectory to the servos under the safety layer",
                       formatter_class=Formatter, epilog=EPILOG)
    p.add_argument("trajectory", help="trajectory JSON (robot-rise/trajectory@1)")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--port", help="serial device or pyserial URL")
    g.add_argument("--mock", action="store_true", help="emulated bus (wire timing on), starting at the trajectory's start")
    p.add_argument("--baud", type=int, help="baud rate [bit/s] (default: from servos.toml)")
    p.add_argument("--robot", metavar="DIR", help="robot directory (default: the embedded OP3)")
    p.add_argument("--speed", type=float, default=1.0, help="time scale, e.g. 0.5 = half speed (default 1)")
    p.add_argument("--approach", type=float, metavar="SECONDS",
                   help="first move slowly from the present posture to the first target (at least SECONDS)")
    p.add_argument("--rate", type=float, default=100.0, help="control rate [Hz] (default 100)")
    p.add_argument("--stop", choices=["hold", "limp"], default="hold", help="stop policy on a fault or Ctrl-C")
    p.add_argument("--allow-unproven", action="store_true",
                   help="run a trajectory whose report does not say it was proven on this robot model")
    p.add_argument("--yes", action="store_true", help="do not ask for confirmation")
    p.add_argument("--log", metavar="FILE", help="CSV log of commanded vs present per cycle")
    p.add_argument("--rt-priority", type=int, metavar="P",
                   help="stream under SCHED_FIFO priority P (1..99; needs root or CAP_SYS_NICE): less jitter on a busy host")
    p.add_argument("--cpu-idle", action="store_true",
                   help="let CPUs enter deep idle states while streaming (default: hold the kernel's CPU "
                        "wake-up latency at 0 us where permitted, as cyclictest does: punctual cycles)")
    p.add_argument("--twin", action="store_true",
                   help="with --mock: the servos move a MuJoCo simulation of the robot (does it stand?)")
    p.add_argument("--scene", help="scene of the twin (default: the scene the report says it was proven in, else flat)")
    p.add_argument("--realtime", action="store_true",
                   help="with --twin: run on the wall clock (default: a simulated clock, as fast as the CPU "
                        "allows and independent of machine load)")
    p.set_defaults(func=run)


def _proven(report: dict, robot_name: str, robot_digest: Callable[[], str]) -> tuple[bool, str]:
    """Whether the trajectory's report (written by the dynamics filter) proves it for this robot.

    Keys read: ``proven`` (true only if the judge passed within limits), ``robot`` (name),
    ``robot_digest`` (sha256 of the robot files, checked when present), ``scene``.
    """
    if report.get("proven") is not True:
        return False, "the trajectory's report does not say it was proven (report.proven is not true)"
    name = report.get("robot")
    if name is None:
        return False, "the trajectory's report does not name the robot it was proven on (report.robot missing)"
    if name != robot_name:
        return False, f"the trajectory was proven on robot {name!r}, not {robot_name!r}"
    digest = report.get("robot_digest")
    if digest is not None:
        ours = robot_digest()
        if digest != ours:
            return False, (f"the trajectory was proven on another version of robot {name!r}: the robot files "
                           f"changed since (report.robot_digest {str(digest)[:12]}..., loaded robot {ours[:12]}...)")
    return True, ""


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from drivers.clock import FakeClock
    from drivers.errors import CommunicationError
    from drivers.executor import Executor, ExecutorConfig
    from drivers.safety import SafetyLimits, StopPolicy, check_limits
    from drivers.servo_map import load_servo_map
    from drivers.session import connect, mock_url_for
    from drivers.startup import disarm_watchdog, engage, preflight
    from robot_rise.model import load_robot
    from robot_rise.trajectory import read_trajectory

    robot = load_robot(args.robot)
    traj = read_trajectory(args.trajectory)
    if traj.robot and traj.robot != robot.name:
        raise RobotRiseError(f"trajectory is for robot {traj.robot!r}, not {robot.name!r}",
                             hint="pass --robot DIR of the robot it was made for")
    if args.twin and not args.mock:
        raise RobotRiseError("--twin needs --mock (the twin moves emulated servos)")
    ok, why = _proven(dict(traj.report), robot.name, robot.digest)
    if not ok:
        if not args.allow_unproven:
            raise RobotRiseError(why, hint="run it through the dynamics filter, or pass --allow-unproven to run it anyway")
        print(f"warning: {why}; running anyway (--allow-unproven)", file=sys.stderr)
    else:
        scene = traj.report.get("scene")
        print(f"proven on robot {robot.name}" + (f" in scene {scene}" if scene else ""))
    smap = load_servo_map(robot.directory / "servos.toml")
    limits = SafetyLimits(smap.lower_rad, smap.upper_rad)
    lim = check_limits(np.asarray(traj.q)[:, smap.index_of(traj.joint_names)], limits)
    if not lim.ok:
        joint = smap.servos[lim.joint_index].joint
        raise RobotRiseError(
            f"trajectory leaves the joint limits: {joint} = {lim.value_rad:.3f} rad at t = "
            f"{float(traj.t[lim.sample_index]):.2f} s (limit {lim.limit_rad:.3f} rad, servos.toml)",
            hint="is it for this robot and in radians? check it with robot-rise check TRAJ")
    if args.log:  # fail before anything is powered, not after torque is on
        try:
            Path(args.log).open("w").close()
        except OSError as e:
            raise RobotRiseError(f"cannot write the log {args.log}: {e.strerror or e}") from e
    port = args.port
    twin = None
    clock = None
    if args.mock:
        if args.twin:
            from robot_rise.sim.twin import MujocoTwin

            scene = args.scene or traj.report.get("scene") or "flat"
            twin = MujocoTwin(robot, scene, start=traj.start)
            if not args.realtime:
                clock = FakeClock()
            print(f"physics twin: robot {robot.name} in scene {scene}; "
                  + ("wall clock" if args.realtime else "simulated clock (timing figures are not wall-clock)"))
            initial = dict(traj.start.joints)
        else:
            initial = dict(zip(traj.joint_names, np.asarray(traj.q)[0]))
        port = mock_url_for(smap, initial_rad=initial, plant=twin, clock=clock)
    config = ExecutorConfig(rate_hz=args.rate, speed=args.speed, approach_s=args.approach,
                            stop_policy=StopPolicy(args.stop),
                            log_path=Path(args.log) if args.log else None,
                            realtime_priority=args.rt_priority,
                            cpu_latency_us=None if args.cpu_idle else 0)
    with connect(smap, port, baud_rate=args.baud) as conn:
        pre = preflight(conn.group)
        print(f"preflight: {len(pre.found)}/{len(smap)} servos, {len(pre.changes)} setting(s) changed, "
              f"{'fast' if pre.fast_read else 'plain'} sync read; {conn.latency.note}")
        if pre.hardware_errors:
            print(f"error: hardware errors at start: {pre.hardware_errors}", file=sys.stderr)
            print("hint: robot-rise servos reboot ID --port PORT", file=sys.stderr)
            return 2
        executor = Executor(conn.group, limits, config)
        fb = conn.group.read_feedback()
        executor.prepare(traj.joint_names, traj.t, traj.q, fb.position_rad)  # refuses a far start
        duration = float(traj.t[-1] - traj.t[0]) / args.speed
        if not args.yes:
            answer = input(f"stream {duration:.1f} s of motion to {len(smap)} servos on {conn.url}? [y/N] ")
            if answer.strip().lower() not in ("y", "yes"):
                print("aborted; nothing moved")
                return 2
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
