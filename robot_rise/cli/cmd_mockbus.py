"""robot-rise mockbus serve: the emulated servo bus on a pseudo-terminal, for any program."""

from __future__ import annotations

import argparse
import dataclasses

from robot_rise.cli._common import Formatter

EPILOG = """examples:
  robot-rise mockbus serve                      # prints the device, e.g. /dev/pts/3
  robot-rise servos scan --port /dev/pts/3      # in another terminal
  robot-rise mockbus serve --twin --scene flat  # servos moved by a MuJoCo simulation of the robot
  robot-rise mockbus serve --link /tmp/ttyDXL --baud 1000000 --duration 60
  robot-rise mockbus serve --protocol 1.0       # Protocol 1.0: MX-28 (1.0 firmware) where the map's model has no 1.0
The device behaves like a USB adapter: unmodified dynamixel-sdk (PortHandler("/dev/pts/3")) works.
It has no latency-timer file and rejects the low-latency ioctl; the driver reports both and carries on.
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("mockbus", help="serve the emulated servo bus on a pseudo-terminal",
                       formatter_class=Formatter, epilog=EPILOG)
    msub = p.add_subparsers(dest="mockbus_cmd", metavar="ACTION", required=True)
    q = msub.add_parser("serve", help="emulate the robot's servos on a pseudo-terminal until Ctrl-C",
                        formatter_class=Formatter, epilog=EPILOG)
    q.add_argument("--robot", metavar="DIR", help="robot directory (default: the embedded OP3)")
    q.add_argument("--baud", type=int, help="bus baud rate [bit/s] (default: from servos.toml)")
    q.add_argument("--protocol", type=float, choices=[1.0, 2.0],
                   help="Dynamixel protocol of the emulated bus (default: servos.toml's [bus] protocol); a model "
                        "that does not speak it is emulated as --servo-model")
    q.add_argument("--servo-model", default=None, metavar="MODEL",
                   help="with --protocol: the model for servos whose own does not speak it "
                        "(default MX-28 on 1.0, XM430-W350 on 2.0)")
    q.add_argument("--no-wire-timing", action="store_true", help="answer at once instead of after the wire time")
    q.add_argument("--twin", action="store_true", help="servo positions come from a MuJoCo simulation of the robot")
    q.add_argument("--scene", default="flat", help="scene of the twin (default: flat)")
    q.add_argument("--posture", metavar="FILE", help="start posture JSON (default: the stand keyframe)")
    q.add_argument("--link", metavar="PATH", help="also make a symlink to the device here")
    q.add_argument("--duration", type=float, metavar="SECONDS", help="stop after this long (default: until Ctrl-C)")
    q.add_argument("--rt-priority", type=int, metavar="P",
                   help="serve under SCHED_FIFO priority P (1..99; needs root or CAP_SYS_NICE): replies on time "
                        "on a busy host, as real servos answer")
    q.set_defaults(func=run_serve)


def run_serve(args: argparse.Namespace) -> int:
    from drivers.clock import realtime_scheduling
    from robot_rise.errors import RobotRiseError
    from drivers.mockbus.pty_server import PtyServer
    from drivers.servo_map import load_servo_map
    from drivers.session import mock_bus_for
    from robot_rise.model import load_robot
    from robot_rise.posture import read_posture
    from robot_rise.posture import stand_posture
    from robot_rise.sim.twin import MujocoTwin

    robot = load_robot(args.robot)
    smap = load_servo_map(robot.directory / "servos.toml")
    if args.baud:
        smap = dataclasses.replace(smap, bus=dataclasses.replace(smap.bus, baud_rate=args.baud))
    if args.protocol is not None and args.protocol != smap.protocol:
        from drivers.servo_map import with_protocol

        smap, replaced = with_protocol(smap, args.protocol, args.servo_model)
        if replaced:
            print(f"note: {len(replaced)} servo(s) emulated as {replaced[0][1]} on Protocol {args.protocol:.1f} "
                  f"(their model {replaced[0][0]} does not speak it)")
    start = read_posture(args.posture, robot) if args.posture else stand_posture(robot)
    twin = MujocoTwin(robot, args.scene, start=start) if args.twin else None
    bus = mock_bus_for(smap, initial_rad=start.joints, wire_timing=not args.no_wire_timing, plant=twin)
    if args.rt_priority is not None and not 1 <= args.rt_priority <= 99:
        raise RobotRiseError(f"--rt-priority {args.rt_priority}: SCHED_FIFO priorities are 1..99")
    with PtyServer(bus, link=args.link) as server, realtime_scheduling(args.rt_priority) as scheduling:
        device = server.device
        print(f"mock bus on {device}: {len(smap)} servos ({robot.name}) at {smap.bus.baud_rate} bit/s, "
              f"Protocol {smap.protocol:.1f}"
              + (f", physics twin in scene {args.scene}" if twin else "")
              + (f", link {args.link}" if args.link else "") + f"; {scheduling}")
        print(f"try: robot-rise servos scan --port {device}   (Ctrl-C stops the bus)", flush=True)
        try:
            server.serve(duration_s=args.duration)
        except KeyboardInterrupt:
            pass
        s = server.stats
    print(f"served {s.replies} replies ({s.bytes_in} bytes in, {s.bytes_out} out); "
          f"{s.late_replies} late by > 0.5 ms (max {s.max_lateness_s * 1e3:.2f} ms)")
    return 0
