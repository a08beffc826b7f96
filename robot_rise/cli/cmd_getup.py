"""robot-rise getup: one shot from the present state: estimate, plan, prove, execute, confirm, retry.

Also the wiring ``getup`` and ``guard`` share (:func:`open_live_session`): the robot as
``robot_rise.live.io.RobotIO`` over ``drivers`` (:class:`robot_rise.cli._bus_io.BusRobotIO`: the servo
group and the OpenCR IMU on one bus, a real port or the emulated bus, optionally moved by the physics twin).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from robot_rise.cli._bus_io import BusRobotIO
from robot_rise.cli._common import Formatter, print_json
from robot_rise.errors import RobotRiseError

if TYPE_CHECKING:
    from robot_rise.live.estimate import PostureEstimator
    from robot_rise.live.getup import GetUpConfig
    from robot_rise.live.planners import KeyframePlanner, RisePlanner
    from robot_rise.model import Robot
    from robot_rise.posture import Posture
    from robot_rise.sim.twin import MujocoTwin

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
    p.add_argument("--whole-proofs", action="store_true",
                   help="replay every get-up whole on every model variant instead of composing its proof with the library "
                        "motions' own, kept in the start proof cache (slower first command)")
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
    proofs (``robot_rise.proof.composed``), all loaded here from the start proof cache, or
    proven once and kept there when the cache is cold (``say`` tells how long)."""
    from drivers.clock import FakeClock
    from drivers.imu import OpenCrImu
    from drivers.mockbus.emulated_imu import EmulatedImu
    from drivers.mockbus.plant import ImuNoise
    from drivers.servo_map import load_servo_map
    from drivers.session import connect, mock_url_for
    from drivers.startup import preflight
    from robot_rise.live.estimate import PostureEstimator
    from robot_rise.live.planners import KeyframePlanner, RisePlanner
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
                _warm_start_proofs(context, say or (lambda s: None))
            planner = RisePlanner(context, budget_s=args.budget, composed=composed)
        estimator = PostureEstimator(robot, args.scene, checker=context.checker)
        io = BusRobotIO(robot, smap, conn, imu_dev, simulated=twin is not None, twin=twin, allow_unproven=stock)
        yield LiveSession(robot, io, planner, estimator, twin, time.monotonic() - t0)
    finally:
        conn.close()


COLD_START_PROOF_S = 1.0  # [s] a start proof that took longer than this was proven, not read from the cache (ours: a read takes ~0.05 s)


def _warm_start_proofs(context: Any, say: Callable[[str], None]) -> int:
    """``RiseContext.warm_start_proofs`` motion by motion: a cold cache is said, with how long it
    will take (from the first proof that was not in the cache); how many compose."""
    motions = context.library.motions
    t0 = time.monotonic()
    ready = 0
    cold = False
    for k, motion in enumerate(motions):
        t = time.monotonic()
        ready += context.start_proof(motion) is not None
        took = time.monotonic() - t
        if took > COLD_START_PROOF_S and not cold:
            cold = True
            left = len(motions) - k - 1
            say(f"start proof cache cold: proving the library motions from rest on every model variant "
                f"({took:.0f} s for {motion.name}; about {took * left:.0f} s more for the other {left}); "
                f"once per robot and library, kept for every command after")
    say(f"{ready} of {len(motions)} library motions compose ({time.monotonic() - t0:.1f} s"
        + (", start proof cache now warm)" if cold else ", from the start proof cache)"))
    return ready


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
        repair = a.start_repair.describe() if a.start_repair is not None else ""
        print(f"attempt {a.attempt}: lying {a.lying or '-'}{err}; think {a.estimate_cpu_s + a.plan_cpu_s:.2f} s CPU; "
              + (f"{repair}; " if repair and a.proven else "")
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
    from robot_rise.live.getup import GetUpConfig, get_up
    from robot_rise.live.health import health_limits_for_supply

    if args.attempts < 1:
        raise RobotRiseError(f"--attempts {args.attempts}: at least 1")
    start = _start_posture(args, args.robot)
    config = scheme_config(args.scheme, GetUpConfig(attempts=args.attempts))
    stock = args.scheme == "stock"
    say = (lambda line: None) if args.json else (lambda line: print(line, flush=True))
    # composed proofs with the cached start proofs, as the guard: the first command in ~2 s, not ~10-20 s
    with open_live_session(args, start=start, stock=stock, composed=not (stock or args.whole_proofs), say=say) as s:
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
