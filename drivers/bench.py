"""Bus benchmark: cycle rate vs the wire-time limit, host CPU per cycle, jitter at 100 Hz.

Run: ``robot-rise bench bus`` (or ``python -m drivers.bench``). Uses the emulator with wire
timing on, 20 XM430-W350 servos, return delay 0.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from drivers.executor import Executor, ExecutorConfig
from drivers.group import FEEDBACK_SIZE
from drivers.protocol import wire_time_s
from drivers.safety import SafetyLimits
from drivers.servo_map import BusSpec, ServoMap, ServoSpec
from drivers.session import connect, mock_url_for
from drivers.startup import engage, preflight

__all__ = ["BusBenchResult", "bench_bus", "main"]


@dataclass(frozen=True)
class BusBenchResult:
    """Figures of one baud rate (times in [s], rates in [Hz])."""

    baud_rate: int
    n_servos: int
    cycle_rate_hz: float
    wire_limit_hz: float
    host_cpu_per_cycle_s: float
    jitter_p99_at_100hz_s: float | None


def _map(n: int, baud: int) -> ServoMap:
    servos = tuple(ServoSpec(i, f"j{i}", "XM430-W350", min=-1.5, max=1.5) for i in range(1, n + 1))
    return ServoMap("bench", BusSpec(baud, 0.0), servos)


def bench_bus(baud_rate: int, *, n_servos: int = 20, cycles: int = 500, jitter_s: float = 0.0) -> BusBenchResult:
    smap = _map(n_servos, baud_rate)
    url = mock_url_for(smap, wire_timing=True)
    with connect(smap, url) as conn:
        group = conn.group
        preflight(group)
        engage(group, watchdog_s=None)
        q = np.zeros(n_servos)
        port = group.bus.port
        for _ in range(20):  # warm-up
            group.write_goals(q)
            group.read_feedback()
        t0 = time.perf_counter()
        c0 = time.thread_time()
        e0 = getattr(port, "emulator_time_s", 0.0)
        for _ in range(cycles):
            group.write_goals(q)
            group.read_feedback()
        wall = time.perf_counter() - t0
        cpu = time.thread_time() - c0 - (getattr(port, "emulator_time_s", 0.0) - e0)
        write_b = 14 + 5 * n_servos
        read_b = (10 + 4 + n_servos) + 8 + n_servos * (4 + FEEDBACK_SIZE)
        limit = 1.0 / wire_time_s(write_b + read_b, baud_rate)
        p99 = None
        if jitter_s > 0:
            ex = Executor(group, SafetyLimits(smap.lower_rad, smap.upper_rad), ExecutorConfig(rate_hz=100.0, hold_s=0.0))
            rep = ex.run(smap.joint_names, np.array([0.0, jitter_s]), np.zeros((2, n_servos)))
            p99 = rep.stats.jitter_p99_s
    return BusBenchResult(baud_rate, n_servos, cycles / wall, limit, cpu / cycles, p99)


def main() -> None:  # pragma: no cover - prints figures
    for baud in (1_000_000, 4_000_000):
        r = bench_bus(baud, jitter_s=3.0 if baud == 1_000_000 else 0.0)
        print(f"{baud / 1e6:.0f} Mbps, {r.n_servos} servos: {r.cycle_rate_hz:.0f} Hz measured vs "
              f"{r.wire_limit_hz:.0f} Hz wire limit ({100 * r.cycle_rate_hz / r.wire_limit_hz:.0f}%); "
              f"host CPU {r.host_cpu_per_cycle_s * 1e3:.3f} ms/cycle"
              + (f"; jitter p99 at 100 Hz {r.jitter_p99_at_100hz_s * 1e3:.3f} ms" if r.jitter_p99_at_100hz_s is not None else ""))


if __name__ == "__main__":  # pragma: no cover
    main()
