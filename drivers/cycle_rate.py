"""How fast a servo group cycles back to back: goal write + feedback read, against the wire limit.

One measurement, for either protocol's group: ``cycles`` cycles as the executor runs them
(goals written deferred, so they leave in the same ``write()`` as the feedback request), timed
on the wall clock, with the host's own CPU time per cycle (the thread's CPU time, less what an
in-process emulator spent inside the port). :func:`bench_protocol1` builds the 20-servo
Protocol 1.0 bus of the benchmark on the emulator.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from drivers.servo_map import BusSpec, ServoMap, ServoSpec

EMULATOR_RT_PRIORITY = 20  # SCHED_FIFO priority of the pty emulator when permitted (servo hardware is punctual)

__all__ = ["EMULATOR_RT_PRIORITY", "CycleRate", "measure_cycle_rate", "protocol1_bench_map", "bench_protocol1", "format_cycle_rate"]


@dataclass(frozen=True)
class CycleRate:
    """Back-to-back cycles of one group.

    Attributes:
        servos: servos in the group.
        baud_rate: [bit/s].
        cycles: cycles run.
        complete: cycles whose feedback held every servo.
        cycles_per_s: measured rate [Hz].
        wire_limit_hz: ``1 / cycle_wire_time_s`` of the group [Hz].
        host_cpu_per_cycle_s: host CPU time per cycle [s] (emulator excluded where measurable).
        wall_per_cycle_s: wall time per cycle [s].
        transport: how the emulator was reached.
    """

    servos: int
    baud_rate: int
    cycles: int
    complete: int
    cycles_per_s: float
    wire_limit_hz: float
    host_cpu_per_cycle_s: float
    wall_per_cycle_s: float
    transport: str = ""

    @property
    def fraction_of_wire_limit(self) -> float:
        return self.cycles_per_s / self.wire_limit_hz


def measure_cycle_rate(group: object, cycles: int, *, warmup: int = 20, transport: str = "") -> CycleRate:
    """Run ``cycles`` goal-write + feedback-read cycles on ``group`` (a ServoGroup or
    ServoGroup1 whose servos are engaged or not: the goals are the present positions)."""
    g = group  # duck-typed: write_goals, read_feedback, bus, ids, cycle_wire_time_s
    fb = g.read_feedback()  # type: ignore[attr-defined]
    q = np.where(fb.valid, fb.position_rad, 0.0)
    for _ in range(warmup):
        g.write_goals(q, defer=True)  # type: ignore[attr-defined]
        g.read_feedback()  # type: ignore[attr-defined]
    port = g.bus.port  # type: ignore[attr-defined]
    e0 = getattr(port, "emulator_time_s", 0.0)
    c0, w0 = time.thread_time(), time.perf_counter()
    complete = 0
    for _ in range(cycles):
        g.write_goals(q, defer=True)  # type: ignore[attr-defined]
        complete += int(g.read_feedback().valid.all())  # type: ignore[attr-defined]
    wall = time.perf_counter() - w0
    cpu = time.thread_time() - c0 - (getattr(port, "emulator_time_s", 0.0) - e0)
    return CycleRate(len(g.ids), g.bus.baud_rate, cycles, complete, cycles / wall,  # type: ignore[attr-defined]
                     1.0 / g.cycle_wire_time_s(), cpu / cycles, wall / cycles, transport)  # type: ignore[attr-defined]


def protocol1_bench_map(n: int = 20, *, model: str = "MX-28", baud_rate: int = 1_000_000) -> ServoMap:
    """``n`` servos of ``model`` on a Protocol 1.0 bus at ``baud_rate``, IDs 1..n."""
    servos = tuple(ServoSpec(i, f"j{i}", model, min=-1.5, max=1.5, protocol=1.0) for i in range(1, n + 1))
    return ServoMap("bench1", BusSpec(baud_rate, 0.0, protocol=1.0), servos)


def bench_protocol1(*, n: int = 20, model: str = "MX-28", baud_rate: int = 1_000_000, cycles: int = 500,
                    transport: str = "pty", emulator_rt_priority: int | None = EMULATOR_RT_PRIORITY) -> CycleRate:
    """The Protocol 1.0 cycle benchmark: ``n`` ``model`` servos on the emulator at ``baud_rate``,
    SYNC_WRITE of goals + BULK_READ of the feedback (MX; a READ each on AX/RX), wire timing on.

    Args:
        transport: ``"pty"``: the emulator in a child process on a pseudo-terminal (the host's
            figures are its own); ``"inprocess"``: the ``dxlsim://`` port in this process.
        emulator_rt_priority: SCHED_FIFO priority of the pty emulator where permitted (normal
            scheduling otherwise, as the 2.0 bus benchmark); None: normal scheduling.
    """
    from drivers.clock import MonotonicClock
    from drivers.mockbus.pty_server import spawn_pty_server
    from drivers.session import connect, mock_url_for
    from drivers.startup import preflight

    smap = protocol1_bench_map(n, model=model, baud_rate=baud_rate)
    if transport == "pty":
        with spawn_pty_server(smap.ids, model=model, baud_rate=baud_rate, wire_timing=True, protocol=1.0,
                              rt_priority=emulator_rt_priority) as server, \
                connect(smap, server.device, clock=MonotonicClock()) as conn:
            preflight(conn.group)
            return measure_cycle_rate(conn.group, cycles, transport=f"pty, emulator {server.scheduling}")
    if transport != "inprocess":
        raise ValueError(f"transport {transport!r}: use 'pty' or 'inprocess'")
    with connect(smap, mock_url_for(smap, wire_timing=True, clock=MonotonicClock())) as conn:
        preflight(conn.group)
        return measure_cycle_rate(conn.group, cycles, transport="in-process dxlsim://")


def format_cycle_rate(r: CycleRate) -> str:
    """One line of the benchmark's output."""
    return (f"Protocol 1.0, {r.servos} servos at {r.baud_rate} bit/s ({r.transport}): {r.cycles_per_s:.1f} cycles/s, "
            f"wire limit {r.wire_limit_hz:.1f} Hz ({r.fraction_of_wire_limit:.2f} of it); "
            f"host CPU {r.host_cpu_per_cycle_s * 1e3:.3f} ms per cycle, wall {r.wall_per_cycle_s * 1e3:.3f} ms; "
            f"{r.complete}/{r.cycles} complete")
