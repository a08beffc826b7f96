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
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from drivers.bench import bench_bus

    for baud in (1_000_000, 4_000_000):
        r = bench_bus(baud, cycles=args.cycles, jitter_s=3.0 if baud == 1_000_000 else 0.0)
        line = (f"{baud / 1e6:.0f} Mbps, {r.n_servos} servos: {r.cycle_rate_hz:.0f} Hz measured vs "
                f"{r.wire_limit_hz:.0f} Hz wire limit (ratio {r.cycle_rate_hz / r.wire_limit_hz:.2f}); "
                f"host CPU {r.host_cpu_per_cycle_s * 1e3:.3f} ms/cycle")
        if r.jitter_p99_at_100hz_s is not None:
            line += f"; jitter p99 at 100 Hz {r.jitter_p99_at_100hz_s * 1e3:.3f} ms"
        print(line)
    return 0
