"""Bus benchmark: cycle rate vs the wire-time limit, host CPU per cycle, jitter at 100 Hz.

Run: ``robot-rise bench bus``. 20 XM430-W350 servos with
return delay 0 and wire timing on. By default the emulator runs in a child process behind a
pseudo-terminal (:mod:`drivers.mockbus.pty_server`), so its Python work is not host time and
the host talks to it through the same kernel path as to a USB adapter; ``transport="inprocess"``
uses the ``dxlsim://`` URL handler instead (emulator work then happens inside the host's
``write``/``read`` and is subtracted from the CPU figure, but still costs wall time).

One cycle = sync write of goal positions (deferred, 114 B) + Fast Sync Read of the 14-byte
indirect feedback block (34 B request + 368 B reply), handed to the kernel in one ``write()``.

Two rates are measured: *sequential* (write, wait, decode, next) and *pipelined* (the next
cycle's goal frame is built while the reply is on the wire and the next request leaves as soon
as the reply is in, before the reply is decoded; see
:meth:`drivers.group.ServoGroup.request_fast_feedback`). Both are compared with the wire limit.

The emulator stands for servo hardware, which answers on time whatever the host does; by
default it runs under ``SCHED_FIFO`` (:data:`EMULATOR_RT_PRIORITY`) when the privilege exists,
so that its own wake-up delays on a busy machine are not charged to the host. The host keeps
its normal scheduling unless ``realtime_priority`` is given. The result names both policies.
As the executor does when it streams, the run holds the kernel's CPU wake-up latency at 0 us
(:func:`drivers.clock.cpu_wakeup_latency`) where permitted, unless ``cpu_latency_us`` is None.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from drivers.clock import SPIN_MARGIN_S, MonotonicClock, cpu_wakeup_latency, realtime_scheduling
from drivers.executor import Executor, ExecutorConfig
from drivers.group import ServoGroup
from drivers.pipeline import pipelined_cycles
from drivers.safety import SafetyLimits
from drivers.servo_map import BusSpec, ServoMap, ServoSpec
from drivers.session import Connection, connect, mock_url_for
from drivers.startup import engage, preflight

__all__ = ["EMULATOR_RT_PRIORITY", "BusBenchResult", "bench_bus", "host_code_cpu",
           "format_result"]

TRANSPORTS = ("pty", "inprocess")
EMULATOR_RT_PRIORITY = 20  # SCHED_FIFO priority of the emulator process (servo hardware is punctual)


@dataclass(frozen=True)
class BusBenchResult:
    """Figures of one baud rate (times in [s], rates in [Hz]).

    Attributes:
        baud_rate: [bit/s].
        n_servos: servos on the bus.
        transport: ``"pty"`` (emulator in a child process) or ``"inprocess"``.
        cycle_rate_hz: back-to-back cycles per second measured.
        wire_limit_hz: 1 / wire time of one cycle's bytes.
        host_cpu_per_cycle_s: host thread CPU time (user + kernel) per back-to-back cycle.
        jitter_p99_at_100hz_s: p99 lateness of cycle starts of the executor at 100 Hz.
        executor_cpu_per_cycle_s: host CPU per executor cycle at 100 Hz (safety, logging
            bookkeeping included).
        fast_read_failures: Fast Sync Reads that failed during the run (fell back).
        timeouts: transactions without a reply during the run.
        jitter_run_completed: the 100 Hz run finished without a fault (if it ran).
        host_code_cpu_per_cycle_s: CPU of the host's own code per cycle with the port replaced
            by a stub answering instantly (no kernel, no emulator): what the Python costs.
        scheduling: the scheduling policy the run had.
    """

    baud_rate: int
    n_servos: int
    transport: str
    cycle_rate_hz: float
    wire_limit_hz: float
    host_cpu_per_cycle_s: float
    jitter_p99_at_100hz_s: float | None
    executor_cpu_per_cycle_s: float | None
    fast_read_failures: int
    timeouts: int
    jitter_run_completed: bool | None = None
    host_code_cpu_per_cycle_s: float | None = None
    scheduling: str = "normal scheduling"
    pipelined_rate_hz: float | None = None
    pipelined_cpu_per_cycle_s: float | None = None
    emulator_scheduling: str = "in-process"
    executor_wait_cpu_per_cycle_s: float | None = None

    @property
    def ratio(self) -> float:
        """Sequential cycle rate / wire limit."""
        return self.cycle_rate_hz / self.wire_limit_hz

    @property
    def pipelined_ratio(self) -> float | None:
        """Pipelined cycle rate / wire limit."""
        return None if self.pipelined_rate_hz is None else self.pipelined_rate_hz / self.wire_limit_hz


def _map(n: int, baud: int) -> ServoMap:
    servos = tuple(ServoSpec(i, f"j{i}", "XM430-W350", min=-1.5, max=1.5) for i in range(1, n + 1))
    return ServoMap("bench", BusSpec(baud, 0.0), servos)


@dataclass(frozen=True)
class _Measured:
    rate_hz: float
    cpu_s: float
    pipelined_rate_hz: float
    pipelined_cpu_s: float
    jitter_p99_s: float | None
    executor_cpu_s: float | None
    executor_wait_cpu_s: float | None
    completed: bool | None
    wire_limit_hz: float  # 1 / the wire time of the cycle the group runs (fast or plain read)


def _sequential(group: ServoGroup, q: np.ndarray, cycles: int) -> None:
    for _ in range(cycles):
        group.write_goals(q, defer=True)
        group.read_feedback()


def _timed(fn: Callable[[], object], cycles: int, port: object, emulator_cpu: bool) -> tuple[float, float]:
    t0 = time.perf_counter()
    c0 = time.thread_time()
    e0 = getattr(port, "emulator_time_s", 0.0) if emulator_cpu else 0.0
    fn()
    wall = time.perf_counter() - t0
    cpu = time.thread_time() - c0
    if emulator_cpu:
        cpu -= getattr(port, "emulator_time_s", 0.0) - e0
    return cycles / wall, cpu / cycles


def _measure(conn: Connection, n_servos: int, cycles: int, jitter_s: float, emulator_cpu: bool) -> _Measured:
    group = conn.group
    preflight(group)
    engage(group, watchdog_s=None)
    q = np.zeros(n_servos)
    port = group.bus.port
    _sequential(group, q, 20)  # warm-up
    rate, cpu = _timed(lambda: _sequential(group, q, cycles), cycles, port, emulator_cpu)
    pipelined_cycles(group, q, 20)
    p_rate, p_cpu = _timed(lambda: pipelined_cycles(group, q, cycles), cycles, port, emulator_cpu)
    p99 = ex_cpu = wait_cpu = None
    completed = None
    if jitter_s > 0:
        smap = group.map
        ex = Executor(group, SafetyLimits(smap.lower_rad, smap.upper_rad), ExecutorConfig(rate_hz=100.0, hold_s=0.0,
                                                                                   cpu_latency_us=None))  # bench_bus holds it
        rep = ex.run(smap.joint_names, np.array([0.0, jitter_s]), np.zeros((2, n_servos)))
        p99, ex_cpu, completed = rep.stats.jitter_p99_s, rep.stats.cpu_mean_s, rep.completed
        wait_cpu = rep.stats.wait_cpu_mean_s
    return _Measured(rate, cpu, p_rate, p_cpu, p99, ex_cpu, wait_cpu, completed, 1.0 / group.cycle_wire_time_s())


class _InstantPort:
    """A port stub for :func:`host_code_cpu`: swallows writes, answers reads with ``reply``."""

    timeout: float | None = None

    def __init__(self, reply: bytes) -> None:
        self.reply = reply

    def write(self, data: bytes) -> int:
        return len(data)

    def read(self, size: int = 1) -> bytes:
        return self.reply

    def reset_input_buffer(self) -> None:
        pass


def host_code_cpu(n_servos: int = 20, *, cycles: int = 2000) -> float:
    """CPU time [s] of one host cycle (goal write + fast feedback read and decode) without I/O."""
    import struct

    from drivers.bus import DynamixelBus
    from drivers.clock import FakeClock
    from drivers.group import ServoGroup
    from drivers.protocol import encode_fast_sync_status

    smap = _map(n_servos, 4_000_000)
    block = struct.pack("<iihBBH", 2048, 0, 0, 0, 30, 120)
    port = _InstantPort(encode_fast_sync_status([(i, 0, block) for i in smap.ids]))
    group = ServoGroup(DynamixelBus(port, baud_rate=4_000_000, clock=FakeClock()), smap, fast_read=True)
    q = np.zeros(n_servos)
    for _ in range(100):
        group.write_goals(q, defer=True)
        group.read_feedback()
    c0 = time.thread_time()
    for _ in range(cycles):
        group.write_goals(q, defer=True)
        group.read_feedback()
    return (time.thread_time() - c0) / cycles


def bench_bus(baud_rate: int, *, n_servos: int = 20, cycles: int = 500, jitter_s: float = 0.0,
              transport: str = "pty", realtime_priority: int | None = None,
              emulator_rt_priority: int | None = EMULATOR_RT_PRIORITY,
              spin_margin_s: float = SPIN_MARGIN_S, cpu_latency_us: int | None = 0) -> BusBenchResult:
    """Measure one baud rate (see the module docstring).

    Args:
        baud_rate: bus speed [bit/s] (1, 2, 3 or 4 Mbps).
        cycles: back-to-back cycles timed (sequential, then pipelined).
        jitter_s: seconds of 100 Hz executor streaming for the jitter figure (0: skip).
        transport: ``"pty"`` or ``"inprocess"``.
        realtime_priority: run the host under SCHED_FIFO at this priority (None: normal).
        emulator_rt_priority: SCHED_FIFO priority of the pty emulator process when permitted
            (None: the emulator inherits the host's scheduling).
        spin_margin_s: busy-waited end of the host clock's sleeps [s] (the executor's start
            precision against its CPU cost; see :data:`drivers.clock.SPIN_MARGIN_S`).
        cpu_latency_us: CPU wake-up latency held during the run [us] (None: CPUs idle freely).
    """
    if transport not in TRANSPORTS:
        raise ValueError(f"transport {transport!r} not in {TRANSPORTS}")
    smap = _map(n_servos, baud_rate)
    if transport == "pty":
        from drivers.mockbus.pty_server import spawn_pty_server

        with spawn_pty_server(smap.ids, baud_rate=baud_rate, wire_timing=True,
                              rt_priority=emulator_rt_priority) as server:
            emulator = server.scheduling
            with realtime_scheduling(realtime_priority) as note, cpu_wakeup_latency(cpu_latency_us) as idle, \
                    connect(smap, server.device, clock=MonotonicClock(spin_s=spin_margin_s)) as conn:
                m = _measure(conn, n_servos, cycles, jitter_s, emulator_cpu=False)
                stats = conn.bus.stats
    else:
        emulator = "in-process"
        with realtime_scheduling(realtime_priority) as note, cpu_wakeup_latency(cpu_latency_us) as idle, \
                connect(smap, mock_url_for(smap, wire_timing=True, clock=MonotonicClock(spin_s=spin_margin_s))) as conn:
            m = _measure(conn, n_servos, cycles, jitter_s, emulator_cpu=True)
            stats = conn.bus.stats
    return BusBenchResult(baud_rate, n_servos, transport, m.rate_hz, m.wire_limit_hz, m.cpu_s,
                          m.jitter_p99_s, m.executor_cpu_s, stats.fast_read_failures, stats.timeouts, m.completed,
                          host_code_cpu(n_servos), f"{note}, {idle}", m.pipelined_rate_hz, m.pipelined_cpu_s, emulator,
                          m.executor_wait_cpu_s)


def format_result(r: BusBenchResult) -> str:
    """One line of figures for the operator."""
    line = (f"{r.baud_rate / 1e6:.0f} Mbps, {r.n_servos} servos ({r.transport}; host {r.scheduling}, "
            f"emulator {r.emulator_scheduling}): wire limit {r.wire_limit_hz:.0f} Hz; "
            f"sequential {r.cycle_rate_hz:.0f} Hz (ratio {r.ratio:.2f}, host CPU "
            f"{r.host_cpu_per_cycle_s * 1e3:.3f} ms/cycle)")
    if r.pipelined_rate_hz is not None and r.pipelined_cpu_per_cycle_s is not None:
        line += (f"; pipelined {r.pipelined_rate_hz:.0f} Hz (ratio {r.pipelined_ratio:.2f}, host CPU "
                 f"{r.pipelined_cpu_per_cycle_s * 1e3:.3f} ms/cycle)")
    if r.host_code_cpu_per_cycle_s is not None:
        line += f"; our code alone {r.host_code_cpu_per_cycle_s * 1e3:.3f} ms/cycle"
    if r.jitter_p99_at_100hz_s is not None:
        line += f"; jitter p99 at 100 Hz {r.jitter_p99_at_100hz_s * 1e3:.3f} ms"
    if r.executor_cpu_per_cycle_s is not None:
        line += f" (executor CPU {r.executor_cpu_per_cycle_s * 1e3:.3f} ms/cycle"
        if r.executor_wait_cpu_per_cycle_s is not None:
            line += f", + {r.executor_wait_cpu_per_cycle_s * 1e3:.3f} ms spinning to the deadline"
        line += ")"
    if r.jitter_run_completed is False:
        line += "; the 100 Hz run ABORTED (see the log)"
    if r.fast_read_failures or r.timeouts:
        line += f"; {r.fast_read_failures} fast-read failures, {r.timeouts} timeouts"
    return line
