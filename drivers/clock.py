"""Time sources: a :class:`Clock` protocol, the real monotonic clock and a fake clock for tests.

The executor, the bus timeouts and the emulator all read time through a ``Clock`` so that timing
logic can be tested deterministically: with :class:`FakeClock`, ``sleep`` just advances time.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Protocol, runtime_checkable

__all__ = ["SPIN_MARGIN_S", "CPU_LATENCY_DEVICE", "Clock", "MonotonicClock", "FakeClock", "realtime_scheduling",
           "cpu_wakeup_latency"]

_log = logging.getLogger(__name__)

# [s] final stretch of a precise sleep that is busy-waited (hybrid sleep: the kernel sleep ends
# this long before the deadline, then the monotonic clock is polled). It absorbs the timer's
# own wake-up delay on an idle core (~50-100 us). A longer margin does not help on a saturated
# machine: there a normal-priority task that wakes is run at the next scheduler tick (up to
# 1/HZ = 4 ms on the benchmark VM) however early it wakes, and it may be preempted while it
# spins; it only costs CPU (measured in BENCHMARKS.md, issue 3). Real-time scheduling is the remedy.
SPIN_MARGIN_S = 0.0003
# Linux PM QoS: while a process holds this file open with a value written, no CPU enters an idle
# state whose exit latency exceeds that value [us] (Documentation/power/pm_qos_interface.rst;
# cyclictest holds it at 0 for the same reason).
CPU_LATENCY_DEVICE = "/dev/cpu_dma_latency"


@runtime_checkable
class Clock(Protocol):
    """A monotonic time source in [s]."""

    def now(self) -> float:
        """Current time [s] (arbitrary origin, monotonic)."""
        ...

    def sleep(self, duration_s: float) -> None:
        """Wait ``duration_s`` [s] (no-op if <= 0)."""
        ...


class MonotonicClock:
    """Real time via ``time.perf_counter``; ``sleep`` is precise to ~50 us.

    Args:
        spin_s: the last part of every sleep is busy-waited for precision [s]; 0 disables it.
    """

    def __init__(self, *, spin_s: float = SPIN_MARGIN_S) -> None:
        self._spin_s = spin_s

    def now(self) -> float:
        return time.perf_counter()

    def sleep(self, duration_s: float) -> None:
        if duration_s <= 0:
            return
        end = time.perf_counter() + duration_s
        coarse = duration_s - self._spin_s
        if coarse > 0:
            time.sleep(coarse)
        while time.perf_counter() < end:
            pass


class FakeClock:
    """Deterministic clock for tests: ``sleep`` advances time instantly.

    Args:
        start_s: initial time [s].
    """

    def __init__(self, start_s: float = 0.0) -> None:
        self._t = float(start_s)

    def now(self) -> float:
        return self._t

    def sleep(self, duration_s: float) -> None:
        if duration_s > 0:
            self._t += duration_s

    def advance(self, duration_s: float) -> None:
        """Move time forward by ``duration_s`` [s]."""
        self.sleep(duration_s)


@contextmanager
def realtime_scheduling(priority: int | None) -> Iterator[str]:
    """Run the block under Linux ``SCHED_FIFO`` at ``priority`` (1..99); yields a note.

    A control loop on a busy host wakes late when other processes hold the CPU; real-time
    scheduling is the standard remedy (the same as ``chrt -f PRIORITY``). Child processes
    started inside the block inherit it. Without the privilege (root or CAP_SYS_NICE) the block
    runs at normal priority and the note says so. ``None`` does nothing.
    """
    if priority is None:
        yield "normal scheduling"
        return
    if not hasattr(os, "sched_setscheduler"):
        yield "real-time scheduling not available on this platform"
        return
    old_policy = os.sched_getscheduler(0)
    old_param = os.sched_getparam(0)
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (PermissionError, OSError, ValueError) as e:
        _log.warning("cannot switch to SCHED_FIFO %d: %s (needs root or CAP_SYS_NICE)", priority, e)
        yield f"SCHED_FIFO {priority} refused ({e}); normal scheduling"
        return
    try:
        yield f"SCHED_FIFO priority {priority}"
    finally:
        os.sched_setscheduler(0, old_policy, old_param)


@contextmanager
def cpu_wakeup_latency(max_us: int | None = 0, *, device: str = CPU_LATENCY_DEVICE) -> Iterator[str]:
    """Keep every CPU out of idle states slower to leave than ``max_us`` [us] in the block.

    A control loop sleeps most of each cycle and is woken by a timer or by the adapter's reply;
    from a deep idle state (or, in a VM, a halted virtual CPU) each wake-up costs tens of
    microseconds, several times per cycle. The PM QoS request (:data:`CPU_LATENCY_DEVICE`) is
    the standard remedy; it costs power (idle CPUs poll) only while the block runs and is
    released when it ends, also if the process dies. Without the file or the permission
    (root, or a udev rule granting it) the block runs unchanged and the note says so.
    ``None`` does nothing.
    """
    if max_us is None:
        yield "CPU idle states unrestricted"
        return
    # the notes are yielded outside the except blocks: an error raised in the block must not
    # carry this OSError as its context
    refused = None
    fd = -1
    try:
        fd = os.open(device, os.O_WRONLY)
        os.write(fd, int(max_us).to_bytes(4, "little", signed=True))
    except OSError as e:
        refused = f"CPU idle states unrestricted ({device}: {e.strerror})"
        _log.info("no CPU wake-up latency request: %s", refused)
        if fd >= 0:
            os.close(fd)
    if refused is not None:
        yield refused
        return
    try:
        yield f"CPU wake-up latency held at {max_us} us"
    finally:
        os.close(fd)
