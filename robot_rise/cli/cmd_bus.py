"""robot-rise bench bus / bus1: Dynamixel bus figures against the emulator (wire timing on)."""

from __future__ import annotations

import argparse
import dataclasses

from robot_rise.cli._common import Formatter, print_json


def register(sub: argparse._SubParsersAction) -> None:
    """No top-level command; the benchmark hangs under ``robot-rise bench``."""


def register_bench(bsub: argparse._SubParsersAction) -> None:
    from drivers.clock import SPIN_MARGIN_S
    from robot_rise.bench.bus import EMULATOR_RT_PRIORITY

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
    p.add_argument("--emulator-rt-priority", type=int, default=EMULATOR_RT_PRIORITY, metavar="P",
                   help=f"pty emulator under SCHED_FIFO priority P where permitted (default {EMULATOR_RT_PRIORITY}; 0: normal)")
    p.add_argument("--spin-ms", type=float, default=None, metavar="MS",
                   help=f"busy-waited end of each sleep [ms] (default {SPIN_MARGIN_S * 1e3:g})")
    p.add_argument("--json", action="store_true", help="print one JSON object (a 'results' list, one per baud rate)")
    p.set_defaults(func=run)
    p = bsub.add_parser("bus1", help="Protocol 1.0: cycles/s of a 20-servo bus vs the wire limit, host CPU per cycle",
                        formatter_class=Formatter,
                        epilog="example:\n  robot-rise bench bus1 --cycles 500\n"
                               "  robot-rise bench bus1 --model AX-18A --transport inprocess")
    p.add_argument("--cycles", type=int, default=500, help="back-to-back cycles (SYNC_WRITE goals + BULK_READ feedback)")
    p.add_argument("--servos", type=int, default=20, help="servos on the bus (default 20)")
    p.add_argument("--model", default="MX-28", help="Protocol 1.0 model (default MX-28: BULK_READ; AX/RX: a READ each)")
    p.add_argument("--baud", type=int, default=1_000_000, help="baud rate [bit/s] (default 1000000)")
    p.add_argument("--transport", choices=["pty", "inprocess"], default="pty",
                   help="emulator in a child process on a pseudo-terminal (default) or in-process (dxlsim://)")
    p.add_argument("--emulator-rt-priority", type=int, default=20, metavar="P",
                   help="pty emulator under SCHED_FIFO priority P where permitted (default 20; 0: normal)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the text")
    p.set_defaults(func=run_bus1)


def run_bus1(args: argparse.Namespace) -> int:
    from drivers.cycle_rate import bench_protocol1, format_cycle_rate

    r = bench_protocol1(n=args.servos, model=args.model, baud_rate=args.baud, cycles=args.cycles,
                        transport=args.transport, emulator_rt_priority=args.emulator_rt_priority or None)
    if args.json:
        print_json(dataclasses.asdict(r))
    else:
        print(format_cycle_rate(r))
    return 0


def run(args: argparse.Namespace) -> int:
    from drivers.clock import SPIN_MARGIN_S
    from robot_rise.bench.bus import bench_bus, format_result

    spin_s = SPIN_MARGIN_S if args.spin_ms is None else args.spin_ms * 1e-3
    results = []
    for baud in args.baud or (1_000_000, 4_000_000):
        r = bench_bus(baud, cycles=args.cycles, jitter_s=args.jitter_seconds, transport=args.transport,
                      realtime_priority=args.rt_priority, emulator_rt_priority=args.emulator_rt_priority or None,
                      spin_margin_s=spin_s, cpu_latency_us=None if args.cpu_idle else 0)
        results.append(dataclasses.asdict(r))
        if not args.json:
            print(format_result(r), flush=True)  # each baud rate as it is measured
    if args.json:
        print_json({"results": results})
    return 0
