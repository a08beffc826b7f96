"""Faults injected into the emulated bus while the live get-up rises on the physics twin: does it stop safely, command no goal outside the joint limits, and say why (issue 16)."""

from __future__ import annotations

import enum
import math
import random
import re
import struct
import time
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass
from types import TracebackType
from typing import Any

import numpy as np

from drivers.control_table import HardwareErrorBits, Register
from drivers.mockbus import MockBus
from drivers.protocol import BROADCAST_ID, Instruction, Packet
from drivers.servo_map import ServoMap, ServoSpec
from robot_rise.live import (
    ExecutionResult,
    GetUpConfig,
    GetUpPlanner,
    Health,
    PostureEstimator,
    RobotIO,
    TruthSource,
    get_up,
)
from robot_rise.model import Robot
from robot_rise.posture import Posture
from robot_rise.sampling import sample_lying_postures
from robot_rise.trajectory import Trajectory

__all__ = [
    "FAULT_WINDOW",
    "PUSH_WINDOW",
    "MOTION_TICKS",
    "LYING_ORDER",
    "LiveFault",
    "FaultRig",
    "OpenRig",
    "GoalWrite",
    "GoalSpy",
    "FaultTrial",
    "run_fault_trial",
    "live_fault_trials",
    "summarize_live_faults",
    "live_faults_table",
]

FAULT_WINDOW = (0.2, 0.7)  # the fault strikes at this share of the get-up's duration (uniform, seeded): mid-rise
# a shove strikes once the body is up off the floor (a shove of a lying body leaves it lying) [share of the duration]
PUSH_WINDOW = (0.7, 0.9)
PUSH_FORCE_N = 60.0  # [N] horizontal, at the torso, for PUSH_S: ours, 12 N s topples the 3.5 kg OP3 twin from any pose
PUSH_S = 0.2
# [ticks] a goal write commands motion when it moves the servo's goal by more than this and lies more than this
# from where the shaft is (a hold writes goal = present; a normal end writes the last goal again)
MOTION_TICKS = 2
LYING_ORDER = ("supine", "prone", "left", "right")  # trial k starts lying LYING_ORDER[(seed + k) % 4]
_REASON_CHARS = 200  # alike reasons are cut to this many characters in the summary


class LiveFault(enum.Enum):
    """What goes wrong while the robot rises."""

    SERVO_SILENT = "servo-silent"  # a servo stops answering (it still hears writes)
    OVERLOAD = "overload"  # a servo raises its Overload hardware error: its firmware shuts its torque off
    BLOCKED = "blocked"  # a joint's shaft is blocked (a jammed gear, an obstacle): it answers, it does not move
    IMU_SILENT = "imu-silent"  # the OpenCR (the IMU, ID 200) stops answering
    PUSH = "push"  # a shove at the torso (a person, a collision): the body leaves the proven motion

    @property
    def on_servo(self) -> bool:
        """The fault strikes one servo (the others: the IMU, the body)."""
        return self not in (LiveFault.IMU_SILENT, LiveFault.PUSH)


@dataclass(frozen=True)
class FaultRig:
    """What one trial runs on; the CLI wires it (the live session over the emulated bus, moved by the twin).

    Attributes:
        io: the robot as the get-up loop sees it, over ``bus``.
        planner: plans and proves a get-up.
        estimator: where the body lies.
        bus: the emulated bus: faults are injected into it, goals spied on it.
        servo_map: the servos; every goal is checked against their limits.
        truth: where the body truly lies (the twin), for the estimate's error.
        upright: whether the twin's torso is upright now (the truth, not the IMU).
        push: shoves the twin's torso: a horizontal force [N] (world x, y) for a duration [s].
    """

    io: RobotIO
    planner: GetUpPlanner
    estimator: PostureEstimator
    bus: MockBus
    servo_map: ServoMap
    truth: TruthSource | None = None
    upright: Callable[[], bool] | None = None
    push: Callable[[tuple[float, float], float], None] | None = None


OpenRig = Callable[[Posture, int], AbstractContextManager[FaultRig]]
"""Opens a rig with the twin lying in the posture, the IMU noise seeded with the int."""


# ---- the bus spy ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class GoalWrite:
    """One goal position a servo received.

    Attributes:
        t_s: bus time it arrived [s].
        servo_id: the servo.
        ticks: the goal [ticks].
        previous_ticks: the goal it last received (None: its first in this run) [ticks].
        present_ticks: where its shaft was [ticks].
    """

    t_s: float
    servo_id: int
    ticks: int
    previous_ticks: int | None
    present_ticks: int

    @property
    def commands_motion(self) -> bool:
        """A new goal away from the shaft (not a hold): see :data:`MOTION_TICKS`."""
        moved = self.previous_ticks is None or abs(self.ticks - self.previous_ticks) > MOTION_TICKS
        return moved and abs(self.ticks - self.present_ticks) > MOTION_TICKS


class GoalSpy:
    """Every goal position and Torque Enable the host writes on an emulated bus, as the servos
    receive them (WRITE, REG_WRITE, SYNC_WRITE, BULK_WRITE, broadcast included), from the moment
    it is made until :meth:`close` (a context manager).

    Attributes:
        goals: every goal position written to a servo of the map, in order.
        torque: (bus time [s], servo ID, Torque Enable value) of every torque write.
        partial: writes that cover only part of the goal register (cannot be checked: counted).
    """

    def __init__(self, bus: MockBus, servo_map: ServoMap) -> None:
        self.bus = bus
        self.servo_map = servo_map
        self.goals: list[GoalWrite] = []
        self.torque: list[tuple[float, int, int]] = []
        self.partial = 0
        self._regs: dict[int, tuple[Register, Register]] = {
            s.id: (s.table["goal_position"], s.table["torque_enable"]) for s in servo_map.servos}
        self._limits = {s.id: s.limit_ticks for s in servo_map.servos}
        self._last: dict[int, int] = {}
        bus.packet_listeners.append(self._on_packet)

    def out_of_limits(self) -> list[GoalWrite]:
        """Goals outside their servo's position limits (the servo map's, in ticks)."""
        return [w for w in self.goals if not self._limits[w.servo_id][0] <= w.ticks <= self._limits[w.servo_id][1]]

    def close(self) -> None:
        if self._on_packet in self.bus.packet_listeners:
            self.bus.packet_listeners.remove(self._on_packet)

    def __enter__(self) -> GoalSpy:
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    def _on_packet(self, now_s: float, p: Packet) -> None:
        params = p.params
        if p.instruction in (Instruction.WRITE, Instruction.REG_WRITE) and len(params) >= 3:
            ids = tuple(self._regs) if p.servo_id == BROADCAST_ID else (p.servo_id,)
            for sid in ids:
                self._span(now_s, sid, params[0] | (params[1] << 8), params[2:])
        elif p.instruction == Instruction.SYNC_WRITE and len(params) >= 4:
            address, size = struct.unpack_from("<HH", params)
            body = params[4:]
            if size and len(body) % (size + 1) == 0:
                for k in range(0, len(body), size + 1):
                    self._span(now_s, body[k], address, body[k + 1: k + 1 + size])
        elif p.instruction == Instruction.BULK_WRITE:
            k = 0
            while k + 5 <= len(params):
                sid, address, size = struct.unpack_from("<BHH", params, k)
                self._span(now_s, sid, address, params[k + 5: k + 5 + size])
                k += 5 + size

    def _span(self, now_s: float, sid: int, address: int, data: bytes) -> None:
        regs = self._regs.get(sid)
        if regs is None:  # not a servo of the map (the IMU)
            return
        end = address + len(data)
        for reg in regs:
            lo, hi = reg.address, reg.address + reg.size
            if address <= lo and hi <= end:
                value = reg.decode(bytes(data[lo - address: hi - address]))
                if reg.name == "goal_position":
                    servo = self.bus.servos.get(sid)
                    present = servo.get("present_position") if servo is not None else value
                    self.goals.append(GoalWrite(now_s, sid, value, self._last.get(sid), present))
                    self._last[sid] = value
                else:
                    self.torque.append((now_s, sid, value))
            elif address < hi and lo < end:
                self.partial += 1


# ---- one trial -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Execution:
    start_s: float
    end_s: float
    result: ExecutionResult


class _FaultingIO:
    """The rig's :class:`RobotIO`, every call passed through; the first ``execute`` arms the fault
    (``arm(trajectory, start_s)``), and every ``execute`` is timed."""

    def __init__(self, io: RobotIO, arm: Callable[[Trajectory, float], None]) -> None:
        self._io = io
        self._arm = arm
        self.executions: list[_Execution] = []

    def now_s(self) -> float:
        return self._io.now_s()

    def sleep(self, duration_s: float) -> None:
        self._io.sleep(duration_s)

    def spent(self, compute_s: float) -> None:
        self._io.spent(compute_s)

    def read_joints(self) -> Mapping[str, float]:
        return self._io.read_joints()

    def read_imu(self) -> Any:
        return self._io.read_imu()

    def health(self) -> Health:
        return self._io.health()

    def execute(self, trajectory: Trajectory) -> ExecutionResult:
        start = self._io.now_s()
        if not self.executions:
            self._arm(trajectory, start)
        result = self._io.execute(trajectory)
        self.executions.append(_Execution(start, self._io.now_s(), result))
        return result

    def go_limp(self) -> None:
        self._io.go_limp()

    def hold(self) -> str:
        return self._io.hold()


@dataclass(frozen=True)
class FaultTrial:
    """One get-up from lying with one fault injected mid-rise, and what the loop made of it.

    Times are on the bus clock (simulated); ``None`` where the fault never struck.

    Attributes:
        kind: the fault (:class:`LiveFault` value).
        trial: 0-based index within the kind.
        seed: seed of the start posture, the IMU noise and the fault's time.
        lying: how the twin lay at the start.
        target: what failed: a servo's label (``joint (id N)``) or ``IMU (id 200)``.
        fault_share: when, as a share of the get-up's duration.
        fault_s: bus time the fault struck [s] (None: no get-up was executed to strike).
        mid_rise: it struck while the first get-up was executing.
        halted: that get-up was stopped (not run to its end).
        stop_after_s: from the fault to the last goal commanding motion in that get-up [s].
        said_after_s: from the fault to the loop saying so: the end of the stopped get-up, or
            the loop's give-up (the IMU is not watched while a get-up streams) [s].
        motion_after_stop: goals commanding motion after the fault outside any get-up (0: none).
        retries: get-ups started after the loop had said so.
        goal_writes: goals written in the trial (every one checked against the limits).
        out_of_limit: goals outside their servo's limits (and ``partial`` goal writes).
        out_of_limit_detail: up to five of them, one line each.
        end: ``limp``, ``holding`` or ``K of N holding`` (torque on), once the loop returned.
        standing: the loop reports standing.
        upright: the twin's torso is upright at the end (None: not known).
        reason: why the loop stopped (its report's reason, else the attempts' reasons).
        names_fault: the reason names what failed (the servo's joint or ID; the IMU).
        stopped_safely: struck mid-rise; the get-up stopped, or ran to its end with the servos
            then holding (blind without the IMU, as designed; or standing, the fault never
            showing); no motion after it outside a new attempt; and the servos end limp, or
            holding a robot that is upright, or (the IMU lost) holding as designed.
        wall_s: wall time of the trial [s].
    """

    kind: str
    trial: int
    seed: int
    lying: str
    target: str
    fault_share: float
    fault_s: float | None
    mid_rise: bool
    halted: bool
    stop_after_s: float | None
    said_after_s: float | None
    motion_after_stop: int
    retries: int
    goal_writes: int
    out_of_limit: int
    out_of_limit_detail: tuple[str, ...]
    end: str
    standing: bool
    upright: bool | None
    reason: str
    names_fault: bool
    stopped_safely: bool
    wall_s: float

    def to_dict(self) -> dict[str, Any]:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items()}


def _moving_joint(trajectory: Trajectory, at_s: float, rng: random.Random) -> str:
    """One of the joints moving fastest at ``at_s`` [s] into ``trajectory``: drawn among those at
    least half as fast as the fastest (both arms of a symmetric motion, a leg pushing)."""
    t = np.asarray(trajectory.t, dtype=float)
    q = np.asarray(trajectory.q, dtype=float)
    k = int(np.clip(np.searchsorted(t, t[0] + at_s), 1, len(t) - 1))
    speed = np.abs(q[k] - q[k - 1]) / max(float(t[k] - t[k - 1]), 1e-9)
    fast = [trajectory.joint_names[j] for j in np.flatnonzero(speed >= 0.5 * float(np.max(speed)))]
    return rng.choice(fast)


def _inject(kind: LiveFault, bus: MockBus, target_id: int) -> None:
    if kind is LiveFault.OVERLOAD:
        bus.faults.hardware_error(target_id, HardwareErrorBits.OVERLOAD)
    elif kind is LiveFault.BLOCKED:
        bus.faults.block(target_id)
    else:
        bus.faults.silence(target_id)


def _end_state(bus: MockBus) -> str:
    on = sum(s.torque_on for s in bus.servos.values())
    n = len(bus.servos)
    return "limp" if on == 0 else "holding" if on == n else f"{on} of {n} holding"


def run_fault_trial(open_rig: OpenRig, robot: Robot, kind: LiveFault, *, trial: int = 0, seed: int = 0,
                    config: GetUpConfig = GetUpConfig()) -> FaultTrial:
    """Lay the twin down (``LYING_ORDER``, a settled random posture), run :func:`get_up`, and
    inject ``kind`` at a random share (:data:`FAULT_WINDOW`) of the first get-up it executes,
    into one of the servos moving fastest then (or the IMU); every goal on the bus is spied on.
    """
    trial_seed = seed + trial
    lying = LYING_ORDER[trial_seed % len(LYING_ORDER)]
    rng = random.Random(f"{kind.value}/{trial_seed}")
    share = rng.uniform(*(PUSH_WINDOW if kind is LiveFault.PUSH else FAULT_WINDOW))
    heading = rng.uniform(-math.pi, math.pi) if kind is LiveFault.PUSH else 0.0  # drawn for a push only: other kinds keep their draws
    start = sample_lying_postures(robot, lying, 1, seed=trial_seed)[0]  # type: ignore[arg-type]
    w0 = time.perf_counter()
    with open_rig(start, trial_seed) as rig, GoalSpy(rig.bus, rig.servo_map) as spy:
        bus = rig.bus
        by_joint: dict[str, ServoSpec] = {s.joint: s for s in rig.servo_map.servos}
        armed: dict[str, Any] = {}
        struck: list[float] = []

        def arm(trajectory: Trajectory, start_s: float) -> None:
            at_s = share * trajectory.duration_s
            if kind.on_servo:
                spec = by_joint.get(_moving_joint(trajectory, at_s, rng)) or rig.servo_map.servos[0]
                target_id, label = spec.id, spec.label
            elif kind is LiveFault.PUSH:
                if rig.push is None:
                    raise ValueError("the rig cannot push its twin")
                target_id, label = -1, f"torso ({PUSH_FORCE_N:.0f} N at {math.degrees(heading):.0f} deg)"
            else:
                if bus.imu is None:
                    raise ValueError("the rig's bus has no IMU to silence")
                target_id, label = bus.imu.id, f"IMU (id {bus.imu.id})"
            armed.update(target_id=target_id, label=label)

            def strike(b: MockBus) -> None:
                struck.append(start_s + at_s)
                if kind is LiveFault.PUSH and rig.push is not None:
                    rig.push((PUSH_FORCE_N * math.cos(heading), PUSH_FORCE_N * math.sin(heading)), PUSH_S)
                else:
                    _inject(kind, b, target_id)

            bus.faults.at(start_s + at_s, strike)

        io = _FaultingIO(rig.io, arm)
        report = get_up(io, rig.planner, rig.estimator, config=config, truth=rig.truth)
        end_s = io.now_s()
        end = _end_state(bus)
        upright = rig.upright() if rig.upright is not None else None
        executions = list(io.executions)
        names = {s.id: s.joint for s in rig.servo_map.servos}
        out = spy.out_of_limits()
        limits = {s.id: s.limit_ticks for s in rig.servo_map.servos}
        goals = list(spy.goals)
        partial = spy.partial
    reasons = tuple(a.why for a in report.attempts)
    reason = report.reason or "; ".join(w for w in reasons if w) or ("standing: nothing to say" if report.standing else "")
    target = str(armed.get("label", "-"))
    fault_s = struck[0] if struck else None
    first = executions[0] if executions else None
    mid_rise = fault_s is not None and first is not None and first.start_s <= fault_s <= first.end_s
    halted = mid_rise and first is not None and not first.result.completed
    stop_after = said_after = None
    motion_after = retries = 0
    if fault_s is not None and first is not None:
        in_first = [w.t_s for w in goals if w.commands_motion and fault_s <= w.t_s <= first.end_s]
        stop_after = (max(in_first) if in_first else fault_s) - fault_s
        said_s = next((e.end_s for e in executions if not e.result.completed and e.end_s >= fault_s), end_s)
        said_after = said_s - fault_s
        motion_after = sum(1 for w in goals if w.commands_motion and w.t_s >= fault_s
                           and not any(e.start_s <= w.t_s <= e.end_s for e in executions))
        retries = sum(1 for e in executions if e.start_s >= said_s)
    if kind.on_servo:
        tid = armed.get("target_id")
        joint = names.get(tid) if tid is not None else None
        names_fault = tid is not None and ((joint is not None and joint in reason) or f"id {tid}" in reason)
        safe_end = end == "limp" or bool(upright)
    elif kind is LiveFault.PUSH:
        # the torso off its proven tilt (the IMU), or a joint off its predicted position first
        names_fault = "falling" in reason or "tracking error" in reason
        safe_end = end == "limp" or bool(upright)
    else:
        names_fault = "IMU" in reason
        safe_end = True  # blind: limp, or holding as the loop leaves it (it may stand)
    # the get-up stopped; or it ran to its end and the servos hold: blind (the IMU lost), or a
    # robot standing whose fault never showed (a blocked joint within the proof's tolerance)
    stopped = halted or (mid_rise and ((kind is LiveFault.IMU_SILENT) or (report.standing and bool(upright))))
    detail = tuple(f"servo {w.servo_id} at {w.t_s:.2f} s: {w.ticks} ticks outside "
                   f"{limits[w.servo_id][0]}..{limits[w.servo_id][1]}" for w in out[:5])
    return FaultTrial(
        kind=kind.value, trial=trial, seed=trial_seed, lying=lying, target=target, fault_share=share,
        fault_s=fault_s, mid_rise=mid_rise, halted=halted, stop_after_s=stop_after, said_after_s=said_after,
        motion_after_stop=motion_after, retries=retries, goal_writes=len(goals), out_of_limit=len(out) + partial,
        out_of_limit_detail=detail, end=end, standing=report.standing, upright=upright, reason=reason,
        names_fault=names_fault, stopped_safely=stopped and motion_after == 0 and safe_end,
        wall_s=time.perf_counter() - w0,
    )


def live_fault_trials(open_rig: OpenRig, robot: Robot, *, kinds: Sequence[LiveFault] = tuple(LiveFault),
                      trials: int = 3, seed: int = 0, config: GetUpConfig = GetUpConfig(),
                      on_trial: Callable[[FaultTrial], None] | None = None) -> list[FaultTrial]:
    """``trials`` runs of :func:`run_fault_trial` per kind (seeds ``seed .. seed + trials - 1``)."""
    if trials < 1:
        raise ValueError(f"trials must be >= 1, got {trials}")
    out: list[FaultTrial] = []
    for kind in kinds:
        for k in range(trials):
            result = run_fault_trial(open_rig, robot, kind, trial=k, seed=seed, config=config)
            out.append(result)
            if on_trial is not None:
                on_trial(result)
    return out


def _template(trial: FaultTrial) -> str:
    """The reason with the failed servo and the numbers left out (to count alike reasons)."""
    text = trial.reason
    m = re.fullmatch(r"(\w+) \(id \d+\)", trial.target)
    if m and LiveFault(trial.kind).on_servo:
        text = text.replace(trial.target, "<servo>").replace(m.group(1), "<servo>")
    text = re.sub(r"\d+(\.\d+)?", "#", text)
    return text if len(text) <= _REASON_CHARS else text[: _REASON_CHARS - 3] + "..."


def _max(values: Sequence[float | None]) -> float | None:
    v = [x for x in values if x is not None and math.isfinite(x)]
    return max(v) if v else None


def summarize_live_faults(trials: Sequence[FaultTrial]) -> dict[str, dict[str, Any]]:
    """Per fault kind: ``trials``, ``mid_rise`` (struck while a get-up executed; in the others
    none was executed: no proven get-up), ``stopped_safely`` (of those struck), ``halted``,
    ``stop_after_max_s`` / ``stop_after_p50_s`` (every trial: a halted get-up's stop, else its
    end), ``stop_after_halted_max_s`` (halted get-ups only), ``said_after_max_s``, ``goal_writes``,
    ``out_of_limit``, ``motion_after_stop``, ``retries``, ``ends`` (count by end state),
    ``names_fault``, ``reasons`` (alike reasons with their count, servo and numbers left out)."""
    out: dict[str, dict[str, Any]] = {}
    for kind in dict.fromkeys(t.kind for t in trials):
        rows = [t for t in trials if t.kind == kind]
        stops = [t.stop_after_s for t in rows if t.stop_after_s is not None]
        out[kind] = {
            "trials": len(rows),
            "mid_rise": sum(t.mid_rise for t in rows),
            "stopped_safely": sum(t.stopped_safely for t in rows if t.mid_rise),
            "halted": sum(t.halted for t in rows),
            "stop_after_max_s": _max(stops),
            "stop_after_halted_max_s": _max([t.stop_after_s for t in rows if t.halted]),
            "stop_after_p50_s": float(np.median(stops)) if stops else None,
            "said_after_max_s": _max([t.said_after_s for t in rows]),
            "goal_writes": sum(t.goal_writes for t in rows),
            "out_of_limit": sum(t.out_of_limit for t in rows),
            "motion_after_stop": sum(t.motion_after_stop for t in rows),
            "retries": sum(t.retries for t in rows),
            "ends": dict(Counter(t.end for t in rows)),
            "names_fault": sum(t.names_fault for t in rows if t.mid_rise),
            "reasons": dict(Counter(_template(t) for t in rows).most_common()),
        }
    return out


def live_faults_table(summary: Mapping[str, Mapping[str, Any]]) -> str:
    """The summary as a Markdown table, then the alike reasons per kind. "Fault to stop": to the
    last goal commanding motion in the struck get-up (halted: the stop; else the get-up's end)."""
    def s(v: float | None) -> str:
        return "-" if v is None else f"{v:.2f}"

    lines = ["| fault | trials | struck mid-rise | get-up halted | stopped safely | fault to stop max, halted / all [s] "
             "| fault to said max [s] | goals written | out of limits | motion after the stop | retries | ends "
             "| reason names it |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- | ---: |"]
    for kind, r in summary.items():
        n, struck = r["trials"], r["mid_rise"]
        ends = ", ".join(f"{k} {v}" for k, v in r["ends"].items())
        lines.append(f"| {kind} | {n} | {struck}/{n} | {r['halted']}/{struck} | {r['stopped_safely']}/{struck} | "
                     f"{s(r['stop_after_halted_max_s'])} / {s(r['stop_after_max_s'])} | {s(r['said_after_max_s'])} | "
                     f"{r['goal_writes']} | {r['out_of_limit']} | {r['motion_after_stop']} | {r['retries']} | {ends} | "
                     f"{r['names_fault']}/{struck} |")
    lines.append("")
    for kind, r in summary.items():
        for text, count in r["reasons"].items():
            lines.append(f"{kind} ({count}x): {text}")
    return "\n".join(lines)
