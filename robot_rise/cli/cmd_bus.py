"""robot-rise bench bus: Dynamixel bus figures against the emulator (wire timing on)."""

from __future__ import annotations

import argparse

from robot_rise.cli._common import Formatter


def register(sub: argparse._SubParsersAction) -> None:
    """No top-level command; the benchmark hangs under ``robot-rise bench``."""


def register_bench(bsub: argparse._SubParsersAction) -> None:
    p = bsub.add_parser("bus", help="cycle rate vs wire limit, host CPU per cycle, jitter at 100 Hz",
                        formatter_class=Formatter, epilog="example:\n  robot-rise bench bus --cycles 500")
    p.add_argument("--cycles", type=int, default=500, help="back-to-back cycles per baud rate")
    p.add_argument("--jitter-seconds", type=float, default=3.0,
                   help="seconds of 100 Hz streaming for the jitter figure (0: skip)")
    p.add_argument("--transport", choices=["pty", "inprocess"], default="pty",
                   help="emulator in a child process on a pseudo-terminal (default) or in-process (dxlsim://)")
    p.add_argument("--baud", type=int, action="append",
                   help="baud rate(s) to measure [bit/s] (default: 1000000 and 4000000)")
    p.add_argument("--rt-priority", type=int, metavar="P",
                   help="run under SCHED_FIFO priority P (1..99; needs root or CAP_SYS_NICE), like chrt -f P")
    p.add_argument("--cpu-idle", action="store_true",
                   help="let CPUs enter deep idle states (default: hold the kernel's CPU wake-up latency at "
                        "0 us where permitted, as the executor does while streaming)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from robot_rise.bench.bus import bench_bus, format_result

    for baud in args.baud or (1_000_000, 4_000_000):
        r = bench_bus(baud, cycles=args.cycles, jitter_s=args.jitter_seconds, transport=args.transport,
                      realtime_priority=args.rt_priority, cpu_latency_us=None if args.cpu_idle else 0)
        print(format_result(r))
    return 0
