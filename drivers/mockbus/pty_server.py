"""Serving an emulated bus on a Linux pseudo-terminal, so that any program can open it.

:class:`PtyServer` opens a pseudo-terminal pair, keeps the master end and answers every
Protocol 2.0 packet written to the slave end (``/dev/pts/N``) from a :class:`MockBus`.
Unmodified dynamixel-sdk (``PortHandler("/dev/pts/N")``), pyserial or our own
:class:`~drivers.bus.DynamixelBus` can open the slave path like a USB adapter.

Timing: with wire timing on, each reply is written to the master when the emulator says it is
fully on the wire (request wire time + return delay + reply wire time, packets queueing on the
half-duplex wire), never earlier. The emulator runs in the server's own thread or process, so
its Python work is not host time; if the emulator itself is slower than the wire, replies are
late and that shows in the host's cycle rate.

A pseudo-terminal has no latency-timer file and rejects the serial low-latency ioctl; the host
side (:mod:`drivers.port`) reports both and carries on.

Baud rate: the server reads the speed the client set on the slave end (``tcgetattr``); bytes
sent at another speed are dropped, as real servos would not understand them. Speeds that
Python's ``termios`` cannot name are accepted.

Run standalone: ``python -m drivers.mockbus --ids 1-20 --baud 1000000 --wire-timing``
(:mod:`drivers.mockbus.__main__`: prints ``DEVICE /dev/pts/N`` first); the operator command is
``robot-rise mockbus serve``.
"""

from __future__ import annotations

import errno
import logging
import os
import select
import signal
import subprocess
import sys
import termios
import threading
import time
import tty
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from drivers.clock import SPIN_MARGIN_S
from drivers.mockbus.emulator import MockBus

__all__ = [
    "DEVICE_LINE_PREFIX",
    "PtyServer",
    "PtyServerStats",
    "PtyServerProcess",
    "spawn_pty_server",
    "tty_baud_rate",
]

_log = logging.getLogger(__name__)

DEVICE_LINE_PREFIX = "DEVICE "  # first stdout line of the standalone server: "DEVICE /dev/pts/N"
_IDLE_STEP_S = 0.01  # [s] the emulator (plant, watchdogs) advances at least this often when idle
_READ_CHUNK = 4096  # [bytes]
_BAUD_BY_TERMIOS: dict[int, int] = {
    getattr(termios, f"B{rate}"): rate
    for rate in (9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 576000, 921600,
                 1000000, 1152000, 1500000, 2000000, 2500000, 3000000, 3500000, 4000000)
    if hasattr(termios, f"B{rate}")
}


def tty_baud_rate(fd: int) -> int | None:
    """Output speed [bit/s] configured on terminal ``fd``, or ``None`` if termios cannot name it."""
    try:
        ospeed = termios.tcgetattr(fd)[5]
    except termios.error:
        return None
    return _BAUD_BY_TERMIOS.get(ospeed)


@dataclass
class PtyServerStats:
    """Counters of one server (mutable, owned by the server)."""

    bytes_in: int = 0
    bytes_out: int = 0
    replies: int = 0
    dropped_wrong_baud: int = 0
    late_replies: int = 0
    max_lateness_s: float = 0.0


class PtyServer:
    """Answers Protocol 2.0 traffic on a pseudo-terminal from ``bus``.

    Args:
        bus: the emulated bus (its clock should be real time: :class:`MonotonicClock`).
        link: optional symlink to create to the slave device (e.g. ``/tmp/ttyDXL``).
        check_baud: drop bytes written at a speed other than the bus baud rate.
        idle_step_s: advance the emulator at least this often without traffic [s].

    Use as a context manager, or call :meth:`open`, :meth:`serve` and :meth:`close`.
    """

    def __init__(self, bus: MockBus, *, link: str | os.PathLike[str] | None = None,
                 check_baud: bool = True, idle_step_s: float = _IDLE_STEP_S) -> None:
        self.bus = bus
        self.link = Path(link) if link is not None else None
        self.check_baud = check_baud
        self.idle_step_s = idle_step_s
        self.stats = PtyServerStats()
        self.device: str | None = None
        self._master: int | None = None
        self._slave: int | None = None
        self._stop = threading.Event()
        self._warned_baud: int | None = None

    def __enter__(self) -> "PtyServer":
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def open(self) -> str:
        """Create the pseudo-terminal; returns the slave device path."""
        if self._master is not None:
            raise RuntimeError("pty server already open")
        master, slave = os.openpty()
        tty.setraw(slave)  # no echo, no line discipline: bytes pass unchanged
        os.set_blocking(master, False)
        self._master, self._slave = master, slave
        self.device = os.ttyname(slave)
        if self.link is not None:
            if self.link.is_symlink() or self.link.exists():
                self.link.unlink()
            self.link.symlink_to(self.device)
        _log.info("mock bus served on %s%s", self.device, f" (link {self.link})" if self.link else "")
        return self.device

    def _open_master(self) -> int:
        self.open()
        if self._master is None:  # pragma: no cover - open() sets it or raises
            raise RuntimeError("pty server failed to open")
        return self._master

    def stop(self) -> None:
        """Ask :meth:`serve` to return (thread-safe, signal-safe)."""
        self._stop.set()

    def close(self) -> None:
        self.stop()
        for fd in (self._master, self._slave):
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass
        self._master = self._slave = None
        if self.link is not None and self.link.is_symlink():
            try:
                self.link.unlink()
            except OSError:
                pass

    def serve(self, *, duration_s: float | None = None) -> None:
        """Answer traffic until :meth:`stop` (or ``duration_s`` [s] of real time)."""
        master = self._master if self._master is not None else self._open_master()
        bus = self.bus
        clock = bus.clock
        pending: deque[tuple[float, bytes]] = deque()
        end = None if duration_s is None else time.perf_counter() + duration_s
        last_advance = clock.now()
        while not self._stop.is_set():
            now = clock.now()
            if end is not None and time.perf_counter() >= end:
                break
            timeout = self.idle_step_s
            if pending:
                timeout = min(timeout, max(0.0, pending[0][0] - now - SPIN_MARGIN_S))
            try:
                readable, _, _ = select.select([master], [], [], timeout)
            except (OSError, ValueError):  # closed under us
                break
            if readable:
                data = self._read(master)
                if data:
                    self._handle(data, pending)
                    last_advance = clock.now()
            now = clock.now()
            if pending and pending[0][0] - now <= SPIN_MARGIN_S:
                while pending[0][0] > clock.now():  # the last stretch: poll for precision
                    pass
                self._flush_due(master, pending)
            elif not readable and now - last_advance >= self.idle_step_s:
                bus.advance(now)  # keep plant, temperatures and watchdogs moving
                last_advance = now

    # ---- internals ----------------------------------------------------------------------
    def _read(self, master: int) -> bytes:
        try:
            return os.read(master, _READ_CHUNK)
        except BlockingIOError:
            return b""
        except OSError as e:
            if e.errno == errno.EIO:  # no slave open right now (cannot happen: we hold one)
                time.sleep(self.idle_step_s)
                return b""
            raise

    def _handle(self, data: bytes, pending: deque[tuple[float, bytes]]) -> None:
        self.stats.bytes_in += len(data)
        if self.check_baud and self._slave is not None:
            baud = tty_baud_rate(self._slave)
            if baud is not None and baud != self.bus.baud_rate:
                self.stats.dropped_wrong_baud += len(data)
                if self._warned_baud != baud:
                    _log.warning("client writes at %d bit/s, the bus runs at %d: bytes ignored",
                                 baud, self.bus.baud_rate)
                    self._warned_baud = baud
                return
        for reply in self.bus.receive(data):
            pending.append((reply.ready_s, reply.data))

    def _flush_due(self, master: int, pending: deque[tuple[float, bytes]]) -> None:
        now = self.bus.clock.now()
        while pending and pending[0][0] <= now:
            ready, data = pending.popleft()
            late = now - ready
            if late > 0.0005:
                self.stats.late_replies += 1
                _log.debug("reply %.3f ms late", late * 1e3)
            self.stats.max_lateness_s = max(self.stats.max_lateness_s, late)
            try:
                os.write(master, data)
            except BlockingIOError:
                _log.debug("client is not reading: reply of %d bytes lost", len(data))
                continue
            self.stats.bytes_out += len(data)
            self.stats.replies += 1


class PtyServerProcess:
    """A standalone pty server in a child process (see :func:`spawn_pty_server`).

    Attributes:
        device: the slave device path to open.
        process: the child process.
    """

    def __init__(self, process: subprocess.Popen[str], device: str) -> None:
        self.process = process
        self.device = device

    @property
    def scheduling(self) -> str:
        """The child's scheduling policy as the kernel reports it, e.g. ``"SCHED_FIFO 20"``."""
        try:
            policy = os.sched_getscheduler(self.process.pid)
            priority = os.sched_getparam(self.process.pid).sched_priority
        except (OSError, AttributeError):
            return "unknown scheduling"
        if policy == getattr(os, "SCHED_FIFO", -1):
            return f"SCHED_FIFO {priority}"
        if policy == getattr(os, "SCHED_RR", -1):
            return f"SCHED_RR {priority}"
        return "normal scheduling"

    def __enter__(self) -> "PtyServerProcess":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self, timeout_s: float = 5.0) -> None:
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
            try:
                self.process.wait(timeout_s)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(timeout_s)
        if self.process.stdout is not None:
            self.process.stdout.close()


def spawn_pty_server(ids: Sequence[int], *, model: str = "XM430-W350", baud_rate: int = 1_000_000,
                     wire_timing: bool = True, return_delay_units: int = 0,
                     rt_priority: int | None = None, startup_timeout_s: float = 20.0,
                     protocol: float = 2.0) -> PtyServerProcess:
    """Start ``python -m drivers.mockbus`` in a child process; wait for its device.

    Args:
        rt_priority: run the emulator under ``SCHED_FIFO`` at this priority when permitted
            (normal scheduling with a warning otherwise; see :attr:`PtyServerProcess.scheduling`).
            Real servos answer on time whatever the host does; an emulator at normal priority
            on a busy machine wakes up late and its lateness would be charged to the host.
        protocol: 2.0 (X series) or 1.0 (:class:`~drivers.mockbus.MockBus1`: ``model`` a 1.0 model).

    Raises:
        RuntimeError: the server did not report a device in time.
    """
    ids_text = ",".join(str(i) for i in ids)
    cmd = [sys.executable, "-m", "drivers.mockbus", "--ids", ids_text, "--model", model,
           "--baud", str(baud_rate), "--delay", str(return_delay_units)]
    if wire_timing:
        cmd.append("--wire-timing")
    if protocol != 2.0:
        cmd += ["--protocol", str(protocol)]
    if rt_priority is not None:
        cmd += ["--rt-priority", str(rt_priority)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
    line = ""
    if proc.stdout is not None:
        ready, _, _ = select.select([proc.stdout], [], [], startup_timeout_s)
        line = proc.stdout.readline() if ready else ""
    if not line.startswith(DEVICE_LINE_PREFIX):
        proc.kill()
        proc.wait()
        raise RuntimeError(f"pty server did not start (got {line!r})")
    return PtyServerProcess(proc, line[len(DEVICE_LINE_PREFIX):].strip())
