"""The 2.0 driver's fault campaign repeated on a Protocol 1.0 bus (issue 43): every goal in the
joint limits, every fault stopped or reported, no traceback.

Run: ``robot-rise bench bus1-faults [--json]``. The bus: 20 servos on Protocol 1.0 at 1 Mbps,
16 MX-28 (1.0 firmware: BULK_READ) and 4 AX-18A (a READ each), asymmetric limits, some servos
reversed (:func:`fault_bench_map`). The executor streams a wave that rides each joint's limits
(:func:`wave`) at 100 Hz under the default HOLD policy while one fault strikes (the strike time
and the struck servo drawn from the seed, at 20-70 % of the wave):

- in-process (the emulator on a fake clock: reproducible, seconds): a share of the status packets
  dropped, corrupted (a flipped bit: the checksum fails) or cut short; a servo gone silent in the
  middle of the BULK_READ list (MX) or among the READs (AX); an Overload alarm bit (Alarm Shutdown
  takes the servo's torque: Torque Limit 0); the motors overheating; the supply sagging to 9 V or
  rising to 15.5 V;
- the host in a child process, streaming over a pseudo-terminal to the emulator in this process:
  SIGTERM (``drivers.startup1.host_stop_guard`` makes it the executor's controlled stop) and
  SIGKILL (no stop is possible: 1.0 has no Bus Watchdog, so the servos must be left holding their
  last goal inside the limits, Torque Limit as the cap and Alarm Shutdown armed, as
  ``drivers.startup1`` documents).

Each row counts the goal positions the servos received (a spy on the emulator's packets: every
SYNC_WRITE, WRITE or REG_WRITE that covers Goal Position), those outside the servo map's limit
ticks, how the fault was stopped (the executor's faults, the stop policy, recovery) or reported
(a fault the run rides through: the statuses the injector took beside the timeouts and bad
checksums the host counted), whether a traceback was seen (an exception out of the executor, a
driver log record with one, "Traceback" on the child's stderr), and the servos' end state.
"""

from __future__ import annotations

import contextlib
import enum
import itertools
import json
import logging
import os
import random
import signal
import subprocess
import sys
import tempfile
import threading
import time
import traceback
from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

import drivers.mockbus as mb
from drivers.clock import FakeClock, MonotonicClock
from drivers.executor import ExecutionReport, Executor, ExecutorConfig
from drivers.mockbus.pty_server import PtyServer
from drivers.protocol import Packet
from drivers.protocol1 import BROADCAST_ID, ErrorBits1, Instruction1
from drivers.safety import SafetyLimits, voltage_limits_for_supply
from drivers.servo_map import BusSpec, ServoMap, ServoSpec
from drivers.session import connect, mock_bus_for
from drivers.startup import engage, preflight
from drivers.startup1 import REQUIRED_SHUTDOWN_BITS, host_stop_guard

__all__ = ["Bus1Fault", "Bus1FaultRow", "GoalSpy1", "fault_bench_map", "wave", "run_bus1_fault", "bus1_fault_campaign",
           "bus1_faults_table"]

WAVE_S = 3.0  # [s] one period of the wave; peak speed 2.6 rad/s, under the 4.8 rad/s step limit
STRIKE_WINDOW = (0.2, 0.7)  # the fault strikes at this share of the wave (uniform, seeded)
RATE_HZ = 100.0  # [Hz] the executor's default rate
REPLY_FAULT_PROBABILITY = 0.02  # share of the status packets a drop / corrupt / truncate fault takes
SETTLE_S = 0.5  # [s] after the run (or the kill) before the end state is read
HOLD_TICKS = 10  # [ticks] a torque-on servo this close to its goal is holding (MX 0.015 rad, AX 0.05 rad)
_GOAL_ADDRESS = 30  # Goal Position (2 bytes) on every 1.0 table
_CHILD_TIMEOUT_S = 60.0  # [s] the child must stream, or exit, within this
_names = itertools.count()


class Bus1Fault(enum.Enum):
    """What goes wrong on the 1.0 bus while the executor streams."""

    DROP = "drop"  # 2 % of the status packets never arrive
    CORRUPT = "corrupt"  # 2 % have one bit flipped: the checksum fails
    TRUNCATE = "truncate"  # 2 % are cut short
    MISSING_MX = "missing-mx"  # an MX in the middle of the BULK_READ list stops answering (it still hears)
    MISSING_AX = "missing-ax"  # an AX-18A stops answering its READ
    OVERLOAD = "overload"  # an MX raises the Overload alarm bit: Alarm Shutdown, Torque Limit 0
    OVERHEATING = "overheating"  # every motor heats 30 000 times faster than the model's
    UNDERVOLTAGE = "undervoltage"  # the supply sags to 9 V
    OVERVOLTAGE = "overvoltage"  # the supply rises to 15.5 V (the AX-18A's own limit is 14 V)
    HOST_TERMINATED = "host-terminated"  # SIGTERM to the streaming host process
    HOST_KILLED = "host-killed"  # SIGKILL to the streaming host process

    @property
    def in_child(self) -> bool:
        """The host streams from a child process (the fault is to that process)."""
        return self in (Bus1Fault.HOST_TERMINATED, Bus1Fault.HOST_KILLED)


@dataclass(frozen=True)
class Bus1FaultRow:
    """One fault's outcome.

    Attributes:
        fault: :class:`Bus1Fault` value.
        goals_written: goal positions the servos received (one per servo per write).
        goals_out_of_limits: of those, outside the servo map's limit ticks.
        stopped: the run stopped on the fault (the executor's stop, or the host killed).
        reported: the fault is in the run's report, or the host counted what it cost.
        how: how it was stopped or reported, in words.
        traceback_seen: an exception escaped the executor or the child, or a driver logged one.
        end_state: the servos after the run (holding in limits / torque off / shaft free).
        safe_end: every servo ended with torque off, its shaft free, or holding inside its limits.
        seconds: wall time of the case [s].
    """

    fault: str
    goals_written: int
    goals_out_of_limits: int
    stopped: bool
    reported: bool
    how: str
    traceback_seen: bool
    end_state: str
    safe_end: bool
    seconds: float

    @property
    def ok(self) -> bool:
        """0 goals out of limits, the fault stopped or reported, no traceback, a safe end."""
        return (self.goals_out_of_limits == 0 and (self.stopped or self.reported) and not self.traceback_seen
                and self.safe_end)

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "ok": self.ok}


def fault_bench_map() -> ServoMap:
    """The campaign's bus: IDs 1-16 MX-28 (limits -1.2..0.9 rad, even IDs reversed), 17-20 AX-18A
    (-0.8..0.8 rad), Protocol 1.0 at 1 Mbps, 12 V."""
    servos = tuple(ServoSpec(i, f"mx{i}", "MX-28", direction=-1 if i % 2 == 0 else 1, min=-1.2, max=0.9, protocol=1.0)
                   for i in range(1, 17))
    servos += tuple(ServoSpec(i, f"ax{i}", "AX-18A", min=-0.8, max=0.8, protocol=1.0) for i in range(17, 21))
    return ServoMap("bus1-faults", BusSpec(1_000_000, 0.0, protocol=1.0), servos)


def wave(smap: ServoMap, seconds: float = WAVE_S) -> tuple[np.ndarray, np.ndarray]:
    """One period of a sine from 0 rad that rides each joint's limits on both sides (clipped at
    them): times [s] shape (T,), angles [rad] shape (T, n) in map order."""
    t = np.linspace(0.0, seconds, int(round(seconds * 20)) + 1)
    amplitude = 1.05 * np.maximum(np.abs(smap.lower_rad), np.abs(smap.upper_rad))
    q = amplitude[None, :] * np.sin(2.0 * np.pi * t / seconds)[:, None]
    return t, np.clip(q, smap.lower_rad, smap.upper_rad)


def _limits(smap: ServoMap) -> SafetyLimits:
    return SafetyLimits(smap.lower_rad, smap.upper_rad, **voltage_limits_for_supply(smap.bus.supply_voltage_v))


# ---- the spy and the end state ---------------------------------------------------------------


class GoalSpy1:
    """Counts every goal position the emulated 1.0 bus receives (from its packet listeners: every
    SYNC_WRITE, WRITE or REG_WRITE covering Goal Position, broadcast included), and those outside
    the servo map's limit ticks (whether or not the servo refused them)."""

    def __init__(self, bus: mb.MockBus, smap: ServoMap) -> None:
        self.limit_ticks = {s.id: s.limit_ticks for s in smap.servos}
        self.goals = 0
        self.goal_packets = 0
        self.out_of_limits: list[tuple[int, int]] = []  # (servo ID, ticks)
        self.last_goals: dict[int, int] = {}  # servo ID -> the last goal it received [ticks]
        bus.packet_listeners.append(self._on_packet)

    def _goal(self, sid: int, data: bytes, address: int) -> None:
        k = _GOAL_ADDRESS - address
        if sid not in self.limit_ticks or address > _GOAL_ADDRESS or len(data) < k + 2:
            return
        ticks = data[k] | (data[k + 1] << 8)
        self.goals += 1
        self.last_goals[sid] = ticks
        lo, hi = self.limit_ticks[sid]
        if not lo <= ticks <= hi:
            self.out_of_limits.append((sid, ticks))

    def _on_packet(self, _now_s: float, p: Packet) -> None:
        params = p.params
        before = self.goals
        if p.instruction == Instruction1.SYNC_WRITE and len(params) >= 2:
            address, length = params[0], params[1]
            step = 1 + length
            for k in range(2, len(params) - step + 1, step):
                self._goal(params[k], params[k + 1 : k + step], address)
        elif p.instruction in (Instruction1.WRITE, Instruction1.REG_WRITE) and params:
            ids = list(self.limit_ticks) if p.servo_id == BROADCAST_ID else [p.servo_id]
            for sid in ids:
                self._goal(sid, params[1:], params[0])
        self.goal_packets += self.goals > before


def _end_state(bus: mb.MockBus, smap: ServoMap, *, last_goals: dict[int, int] | None = None) -> tuple[bool, str]:
    """Every servo torque off, free (Torque Limit 0) or holding inside its limits? With
    ``last_goals`` (the host was killed) also: holding the last goal it received, its Torque Limit
    at most Max Torque and Alarm Shutdown armed (what remains without a host)."""
    holding = off = free = 0
    bad: list[str] = []
    for spec in smap.servos:
        s = bus.servo(spec.id)
        lo, hi = spec.limit_ticks
        goal, present = s.get("goal_position"), s.get("present_position")
        if last_goals is not None and (s.get("torque_limit") > s.get("max_torque")
                       or s.get("alarm_shutdown") & REQUIRED_SHUTDOWN_BITS != REQUIRED_SHUTDOWN_BITS
                       or goal != last_goals.get(spec.id, goal)):
            bad.append(f"servo {spec.id}: Torque Limit {s.get('torque_limit')}, Alarm Shutdown "
                       f"{s.get('alarm_shutdown')}, goal {goal} (last sent {last_goals.get(spec.id)})")
        elif not s.torque_on:
            off += 1
        elif s.get("torque_limit") == 0:
            free += 1
        elif lo <= goal <= hi and abs(present - goal) <= HOLD_TICKS:
            holding += 1
        else:
            bad.append(f"servo {spec.id}: goal {goal} (limits {lo}..{hi}), present {present}")
    parts = [f"{n} {what}" for n, what in ((holding, "holding in limits"), (off, "torque off"),
                                           (free, "free (alarm shutdown)")) if n]
    return not bad, ", ".join(parts + bad)


@contextlib.contextmanager
def _tracebacks() -> Iterator[list[str]]:
    """Collects the drivers' log records that carry a traceback while the block runs."""
    seen: list[str] = []

    class _Catch(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            if record.exc_info:
                seen.append(record.getMessage())

    handler = _Catch(level=logging.ERROR)
    logger = logging.getLogger("drivers")
    logger.addHandler(handler)
    try:
        yield seen
    finally:
        logger.removeHandler(handler)


# ---- the in-process faults -------------------------------------------------------------------


def _strike(kind: Bus1Fault, bus: mb.MockBus, target: int) -> None:
    f = bus.faults
    if kind is Bus1Fault.DROP:
        f.drop_probability = REPLY_FAULT_PROBABILITY
    elif kind is Bus1Fault.CORRUPT:
        f.corrupt_probability = REPLY_FAULT_PROBABILITY
    elif kind is Bus1Fault.TRUNCATE:
        f.truncate_probability = REPLY_FAULT_PROBABILITY
    elif kind in (Bus1Fault.MISSING_MX, Bus1Fault.MISSING_AX):
        f.silence(target)
    elif kind is Bus1Fault.OVERLOAD:
        f.hardware_error(target, ErrorBits1.OVERLOAD)
    elif kind is Bus1Fault.OVERHEATING:
        f.heating_gain = 3e4
    elif kind is Bus1Fault.UNDERVOLTAGE:
        f.input_voltage_v = 9.0
    elif kind is Bus1Fault.OVERVOLTAGE:
        f.input_voltage_v = 15.5
    else:  # pragma: no cover - the child faults do not strike the bus
        raise ValueError(f"{kind.value} does not strike the bus")


def _target(kind: Bus1Fault, smap: ServoMap, rng: random.Random) -> int:
    """The struck servo: an AX for missing-ax, else an MX off both ends of the BULK_READ list."""
    if kind is Bus1Fault.MISSING_AX:
        return rng.choice([s.id for s in smap.servos if not s.table.bulk_read])
    mx = [s.id for s in smap.servos if s.table.bulk_read]
    return rng.choice(mx[2:-2])


def _how_stopped(rep: ExecutionReport) -> str:
    kinds = ", ".join(dict.fromkeys(f.kind.value for f in rep.faults))
    text = f"{kinds} ({rep.stop_policy.value} stop): {rep.faults[0].message}"
    if len(rep.faults) > 1:
        text += f" (+{len(rep.faults) - 1} more)"
    if rep.recovery is not None:
        text += f"; recovered {list(rep.recovery.recovered) or 'none'}"
        if rep.recovery.failed:
            text += f", not {list(rep.recovery.failed)}"
    return text


def _run_inprocess(kind: Bus1Fault, smap: ServoMap, seed: int) -> Bus1FaultRow:
    w0 = time.perf_counter()
    rng = random.Random(f"{seed}:{kind.value}")
    clock = FakeClock(100.0)
    faults = mb.FaultInjector(seed=seed, input_voltage_v=smap.bus.supply_voltage_v)
    bus = mock_bus_for(smap, clock=clock, wire_timing=True, faults=faults)
    spy = GoalSpy1(bus, smap)
    name = f"bus1-faults-{next(_names)}"
    url = mb.attach(name, bus)
    errors: list[str] = []
    rep: ExecutionReport | None = None
    try:
        with _tracebacks() as logged, connect(smap, url) as conn:
            group = conn.group
            preflight(group)
            engage(group)
            t, q = wave(smap)
            target = _target(kind, smap, rng)
            bus.faults.at(clock.now() + rng.uniform(*STRIKE_WINDOW) * WAVE_S, lambda b: _strike(kind, b, target))
            try:
                rep = Executor(group, _limits(smap), ExecutorConfig(rate_hz=RATE_HZ)).run(smap.joint_names, t, q)
            except Exception:  # noqa: BLE001 - the executor reports faults; anything raised is a finding
                errors.append(traceback.format_exc())
            stats = conn.bus.stats
            clock.sleep(SETTLE_S)
            bus.advance()
            safe, end = _end_state(bus, smap)
        errors += logged
    finally:
        mb.detach(name)
    taken = faults.dropped + faults.corrupted + faults.truncated
    counted = (f"the bus took {taken} status(es), the host counted {stats.timeouts} timeouts and "
               f"{stats.corrupt_replies} bad replies")
    stopped = rep is not None and bool(rep.faults)
    if rep is None:
        how = f"raised: {errors[0].strip().splitlines()[-1]}"
        reported = False
    elif stopped:
        how = _how_stopped(rep) + (f"; {counted}" if taken else "")
        reported = True
    else:  # a fault the run rides through (retries, re-reads): reported if the host noticed what it cost
        reported = taken > 0 and stats.timeouts + stats.corrupt_replies > 0
        how = f"ridden through and counted: {counted}; run completed"
    return Bus1FaultRow(kind.value, spy.goals, len(spy.out_of_limits), stopped, reported, how, bool(errors), end,
                        safe, time.perf_counter() - w0)


# ---- the host in a child process -------------------------------------------------------------


def _stream_child(device: str, report_path: str) -> int:
    """The child: preflight, engage and stream the wave to ``device`` under the host stop guard;
    the report goes to ``report_path`` as JSON."""
    smap = fault_bench_map()
    with connect(smap, device) as conn:
        group = conn.group
        preflight(group)
        engage(group)
        t, q = wave(smap)
        with host_stop_guard(group):
            rep = Executor(group, _limits(smap), ExecutorConfig(rate_hz=RATE_HZ, cpu_latency_us=None)).run(
                smap.joint_names, t, q)
    Path(report_path).write_text(json.dumps({
        "completed": rep.completed, "stop_policy": rep.stop_policy.value, "cycles": rep.stats.cycles,
        "faults": [[f.kind.value, f.message] for f in rep.faults]}), encoding="utf-8")
    return 0


def _strike_child(device: str, spy: GoalSpy1, strike_after: int,
                  sig: signal.Signals) -> tuple[int, int, str, dict[str, Any] | None]:
    """Start the streaming child on ``device``, send it ``sig`` once the stream has sent
    ``strike_after`` goal packets, wait for it; returns (goal packets at the strike, exit code,
    its stderr, its report or None)."""
    with tempfile.TemporaryDirectory(prefix="robot-rise-bus1-faults-") as tmp:
        report_path = Path(tmp) / "report.json"
        code = f"import sys; from {__name__} import _stream_child; sys.exit(_stream_child(sys.argv[1], sys.argv[2]))"
        child = subprocess.Popen([sys.executable, "-c", code, device, str(report_path)],
                                 stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        try:
            deadline = time.monotonic() + _CHILD_TIMEOUT_S
            # engage writes one goal packet (goal = present); the stream's packets follow it
            while spy.goal_packets < strike_after + 1 and child.poll() is None and time.monotonic() < deadline:
                time.sleep(0.002)
            struck_at = spy.goal_packets
            if child.poll() is None:
                os.kill(child.pid, sig)
            _, stderr = child.communicate(timeout=_CHILD_TIMEOUT_S)
        finally:
            if child.poll() is None:
                child.kill()
                child.wait()
        report = json.loads(report_path.read_text(encoding="utf-8")) if report_path.exists() else None
    return struck_at, child.returncode, stderr, report


def _run_child(kind: Bus1Fault, smap: ServoMap, seed: int) -> Bus1FaultRow:
    w0 = time.perf_counter()
    rng = random.Random(f"{seed}:{kind.value}")
    bus = mock_bus_for(smap, clock=MonotonicClock(), wire_timing=True)
    spy = GoalSpy1(bus, smap)
    strike_after = int(rng.uniform(*STRIKE_WINDOW) * WAVE_S * RATE_HZ)  # goal writes of the stream
    sig = signal.SIGKILL if kind is Bus1Fault.HOST_KILLED else signal.SIGTERM
    server = PtyServer(bus)
    device = server.open()
    thread = threading.Thread(target=server.serve, name="bus1-faults-emulator", daemon=True)
    thread.start()
    try:
        struck_at, returncode, stderr, report = _strike_child(device, spy, strike_after, sig)
        time.sleep(SETTLE_S)  # the servos settle on what they were last told
    finally:
        server.stop()
        thread.join(5.0)
        server.close()
    bus.advance()  # to now: the end state is not the serving thread's last step
    safe, end = _end_state(bus, smap, last_goals=spy.last_goals if kind is Bus1Fault.HOST_KILLED else None)
    tb = "Traceback" in stderr
    if kind is Bus1Fault.HOST_KILLED:
        stopped = reported = returncode == -signal.SIGKILL and safe
        how = (f"SIGKILL after {struck_at} goal writes (exit {returncode}): no controlled stop is possible without a "
               "Bus Watchdog; " + ("every servo kept the last goal it received, Torque Limit <= Max Torque, Alarm "
                                   "Shutdown (overload, overheating) armed" if safe else "the servos were NOT left safe"))
    elif report is None:
        stopped = reported = False
        how = f"SIGTERM after {struck_at} goal writes: no report (exit {returncode})"
    else:
        stopped = not report["completed"] and bool(report["faults"])
        reported = any(k == "interrupted" for k, _ in report["faults"])
        how = (f"SIGTERM after {struck_at} goal writes: stopped ({report['stop_policy']}) after {report['cycles']} "
               f"cycles: " + "; ".join(f"{k}: {m}" for k, m in report["faults"]) + f"; exit {returncode}")
    return Bus1FaultRow(kind.value, spy.goals, len(spy.out_of_limits), stopped, reported, how, tb, end, safe,
                        time.perf_counter() - w0)


# ---- the campaign ----------------------------------------------------------------------------


def run_bus1_fault(kind: Bus1Fault, *, seed: int = 0, smap: ServoMap | None = None) -> Bus1FaultRow:
    """One fault on the 1.0 bus (see the module docstring); ``smap`` only for in-process faults
    (the child streams to :func:`fault_bench_map`)."""
    if kind.in_child:
        if smap is not None:
            raise ValueError(f"{kind.value}: the child streams the campaign's own map (fault_bench_map); pass no smap")
        return _run_child(kind, fault_bench_map(), seed)
    return _run_inprocess(kind, smap or fault_bench_map(), seed)


def bus1_fault_campaign(kinds: Sequence[Bus1Fault] = tuple(Bus1Fault), *, seed: int = 0) -> list[Bus1FaultRow]:
    """Every fault of ``kinds`` in turn, one row each."""
    return [run_bus1_fault(k, seed=seed) for k in kinds]


def bus1_faults_table(rows: Sequence[Bus1FaultRow]) -> str:
    """The rows as a Markdown table, with a one-line verdict."""
    lines = ["| fault | goals written | out of limits | stopped or reported (how) | traceback | end state |",
             "| --- | ---: | ---: | --- | :---: | --- |"]
    for r in rows:
        verdict = "stopped" if r.stopped else "reported" if r.reported else "NEITHER"
        lines.append(f"| {r.fault} | {r.goals_written} | {r.goals_out_of_limits} | {verdict}: {r.how} | "
                     f"{'YES' if r.traceback_seen else 'no'} | {r.end_state}{'' if r.safe_end else ' (UNSAFE)'} |")
    ok = sum(r.ok for r in rows)
    lines.append("")
    lines.append(f"{ok} of {len(rows)} faults: 0 goals out of limits, stopped or reported, no traceback, safe end; "
                 f"{sum(r.goals_written for r in rows)} goals written, {sum(r.goals_out_of_limits for r in rows)} out "
                 f"of limits, {sum(r.traceback_seen for r in rows)} tracebacks, {sum(r.seconds for r in rows):.1f} s")
    return "\n".join(lines)
