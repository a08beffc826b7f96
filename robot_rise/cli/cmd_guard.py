"""robot-rise guard: watch the IMU, go limp while falling, get up once fallen; the push benchmark."""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from typing import TYPE_CHECKING

from robot_rise.cli._common import Formatter, print_json
from robot_rise.cli.cmd_getup import add_live_args, open_live_session, print_getup_report, scheme_config
from robot_rise.errors import RobotRiseError

if TYPE_CHECKING:
    from robot_rise.bench.pushes import PushOutcome
    from robot_rise.live.guard import GuardEvent
    from robot_rise.model import Robot
    from robot_rise.sim.twin import MujocoTwin

STOCK_EPISODE_S = 30.0  # [s] a stock-scheme episode ends here: a robot on its side is never seen fallen

EPILOG = """examples:
  robot-rise guard --port /dev/ttyUSB0                            # until Ctrl-C
  robot-rise guard --mock --twin --duration 30                    # the simulated robot, 30 s
  robot-rise guard --mock --twin --pushes 20 --seed 1 --json      # push it over 20 times
  robot-rise guard --mock --twin --pushes 20 --seed 1 --scheme stock   # the stock OP3's scheme
Falling (the IMU's tilt growing fast, or a fast turn about a horizontal axis): the servos go limp
at once. Fallen and still: estimate the posture, plan and prove a get-up, execute it, confirm
standing; at most --attempts tries, then limp until the robot is stood up by hand. Ctrl-C stops
safely: a standing robot keeps holding, a lying one goes limp.
--pushes N (with --mock --twin): push the standing twin over N times (random direction and
strength, seeded) and report per push: max_tilt_deg, lying, first_command_after_s (from
fallen-and-still to the first rising command), standing, standing_after_s (from the push),
attempts; --json prints them in a 'pushes' list with a 'summary'.
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("guard", help="watch the IMU and get up whenever the robot has fallen (or push the twin over)",
                       formatter_class=Formatter, epilog=EPILOG)
    add_live_args(p)
    p.add_argument("--attempts", type=int, default=3, help="tries per fall before giving up (default 3)")
    p.add_argument("--duration", type=float, metavar="SECONDS",
                   help="stop after this long on the bus clock (default: until Ctrl-C)")
    p.add_argument("--pushes", type=int, metavar="N", help="with --mock --twin: push the standing twin over N times")
    p.add_argument("--force", type=float, nargs=2, metavar=("LOW", "HIGH"), default=(20.0, 60.0),
                   help="push strength range [N], each push 0.1 s at the torso (default 20 60)")
    p.add_argument("--json", action="store_true", help="print the pushes (or events) as JSON")
    p.add_argument("--whole-proofs", action="store_true",
                   help="replay every get-up whole on every model variant instead of composing its proof with the library "
                        "motions' own, precomputed at start (slower first command, no settle before the library motion)")
    p.set_defaults(func=run)


class TwinPusher:
    """``robot_rise.bench.pushes.Pusher`` on the physics twin."""

    def __init__(self, robot: Robot, twin: MujocoTwin) -> None:
        self.robot = robot
        self.twin = twin

    def push(self, force_heading_n: tuple[float, float], duration_s: float) -> None:
        from robot_rise.posture import yaw_rad

        yaw = yaw_rad(self.twin.posture().root_quat_wxyz)
        fx, fy = force_heading_n
        c, s = math.cos(yaw), math.sin(yaw)
        self.twin.push((c * fx - s * fy, s * fx + c * fy, 0.0), duration_s)

    def reset_standing(self) -> None:
        from robot_rise.posture import stand_posture

        self.twin.reset(stand_posture(self.robot))


def _push_line(o: PushOutcome) -> str:
    def f(v: float | None) -> str:
        return "-" if v is None else f"{v:.2f}"

    return (f"push {o.push:3d}: {o.force_n:4.0f} N at {o.heading_deg:+5.0f} deg; max tilt {o.max_tilt_deg:5.1f} deg; "
            + (f"lying {o.lying or '-'}; first command {f(o.first_command_after_s)} s; "
               + (f"standing {f(o.standing_after_s)} s after the push" if o.standing else "NOT standing")
               + f"; attempts {o.attempts}" + ("" if o.standing else f" ({'; '.join(r for r in o.reasons if r)})")
               if o.toppled else "withstood"))


def run(args: argparse.Namespace) -> int:
    from robot_rise.bench.pushes import PushConfig, push_trials, summarize_pushes
    from robot_rise.live.getup import GetUpConfig
    from robot_rise.live.guard import guard
    from robot_rise.live.health import health_limits_for_supply

    if args.attempts < 1:
        raise RobotRiseError(f"--attempts {args.attempts}: at least 1")
    if args.pushes is not None:
        if not (args.mock and args.twin):
            raise RobotRiseError("--pushes needs --mock --twin (it pushes the simulated robot)")
        if args.pushes < 1:
            raise RobotRiseError(f"--pushes {args.pushes}: at least 1")
        low, high = args.force
        if not 0.0 < low <= high:
            raise RobotRiseError(f"--force {low} {high}: need 0 < LOW <= HIGH")
    if args.duration is not None and not args.duration > 0:
        raise RobotRiseError(f"--duration {args.duration}: must be > 0")
    stock = args.scheme == "stock"
    config = scheme_config(args.scheme, GetUpConfig(attempts=args.attempts))
    say = (lambda s: None) if args.json else (lambda s: print(s, flush=True))
    with open_live_session(args, stock=stock, composed=not (stock or args.whole_proofs), say=say) as s:
        io = s.io
        config = dataclasses.replace(config, health=health_limits_for_supply(io.map.bus.supply_voltage_v))
        if not args.json:
            print(f"robot {s.robot.name} on {io.connection.url}: {len(io.map)} servos and the IMU answer; "
                  f"ready in {s.setup_s:.1f} s" + ("; physics twin on a simulated clock" if s.twin else ""), flush=True)
        if args.pushes is not None:
            assert s.twin is not None
            outcomes = push_trials(io, s.planner, s.estimator, TwinPusher(s.robot, s.twin), n=args.pushes,
                                   seed=args.seed, config=config,
                                   push=PushConfig(force_n=tuple(args.force), episode_s=STOCK_EPISODE_S if stock else 90.0),
                                   truth=s.truth,
                                   on_push=lambda o: print(_push_line(o), flush=True,
                                                           file=sys.stderr if args.json else sys.stdout))
            io.go_limp()
            summary = summarize_pushes(outcomes, max_attempts=args.attempts)
            if args.json:
                print_json({"robot": s.robot.name, "scheme": args.scheme, "seed": args.seed, "force_n": list(args.force),
                            "pushes": [o.to_dict() for o in outcomes], "summary": summary})
            else:
                a = summary["all"]
                print(f"{summary['toppled']} of {summary['pushes']} pushes toppled it; of those, standing again: "
                      f"{_pct(a['standing'])}, within {summary['within_limit_s']:.0f} s: {_pct(a['within_s'])}, "
                      f"within {args.attempts} attempts: {_pct(a['within_attempts'])}; first command p95 "
                      f"{_num(a['first_command_p95_s'])} s")
            return 0 if all(o.standing for o in outcomes if o.toppled) else 1
        t0 = io.now_s()
        events: list[dict] = []

        def on_event(e: GuardEvent) -> None:
            if args.json:
                events.append({"t_s": e.t_s - t0, "event": e.kind.value, "detail": e.detail,
                               "report": e.report.to_dict() if e.report is not None else None})
                return
            print(f"{e.t_s - t0:8.2f} s  {e.kind.value}: {e.detail}", flush=True)
            if e.report is not None:
                print_getup_report(e.report, t_origin=t0)

        stop = (lambda: io.now_s() - t0 >= args.duration) if args.duration is not None else (lambda: False)
        state = guard(io, s.planner, s.estimator, config=config, stop=stop, on_event=on_event, truth=s.truth)
        if args.json:
            print_json({"robot": s.robot.name, "events": events, "state": state.tracker.state.value,
                        "limp": state.limp})
        else:
            print(f"guard stopped after {io.now_s() - t0:.1f} s: robot {state.tracker.state.value}, "
                  + ("servos limp" if state.limp else "servos holding"))
    return 0


def _pct(v: float | None) -> str:
    return "-" if v is None else f"{100 * v:.0f} %"


def _num(v: float | None) -> str:
    return "-" if v is None else f"{v:.2f}"
