"""The streaming executor: a fixed-rate loop that sends safe targets and watches feedback.

Single-threaded against a monotonic deadline: cycle k starts at ``t0 + k / rate``. Each cycle:
interpolate the trajectory, pass the target through :func:`drivers.safety.safe_target`, one
sync write of goals, one (fast) sync read of feedback, judge it with
:func:`drivers.safety.evaluate_feedback` (and, when ``ExecutorConfig.expected`` gives where the
joints should be, :func:`drivers.safety.evaluate_expected` instead of the absolute tracking
limit), log a row. On a fault or Ctrl-C: a controlled stop by
policy, then (for HOLD) bounded recovery of shut-down servos so the robot keeps holding.
A cycle that starts more than one period late (a stall of the host or the bus) re-anchors the
schedule: the rest of the trajectory is delayed, never replayed back to back (which would move
the servos faster than the per-cycle step limit intends).

The trajectory is plain arrays (joint names, t, q); nothing here knows robot_rise types.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import IO

import numpy as np
from numpy.typing import NDArray

from drivers.clock import MonotonicClock, cpu_wakeup_latency, realtime_scheduling
from drivers.control_table import WATCHDOG_UNIT_S
from drivers.errors import CommunicationError, SafetyError
from drivers.group import Feedback, ServoGroup
from drivers.imu import Imu
from drivers.safety import (
    ExpectedPositions,
    ExpectedTilt,
    Fault,
    FaultKind,
    SafetyLimits,
    StopPolicy,
    approach_path,
    check_start,
    band_deviation,
    evaluate_expected,
    evaluate_feedback,
    evaluate_tilt,
    limp_pwm_ramp,
    require_inside_limits,
    safe_target,
)
from drivers.startup import RecoveryReport, arm_watchdog, disarm_watchdog, recover

__all__ = ["ExecutorConfig", "CycleStats", "ExecutionReport", "Executor", "interpolate", "DEFAULT_RATE_HZ"]

_log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]
MIN_RATE_HZ = 20.0  # [Hz] slowest control rate accepted
# The control rate. The core's robot_rise.filter.command_limits.DEFAULT_RATE_HZ repeats it (the
# filter proves trajectories for it; sim_tests/test_command_limits.py holds them equal).
DEFAULT_RATE_HZ = 100.0  # [Hz]


@dataclass(frozen=True)
class ExecutorConfig:
    """Executor settings.

    Attributes:
        rate_hz: control rate [Hz].
        speed: trajectory time scale (0.5 = half speed).
        approach_s: if set, move from the present posture to the first target over at least
            this many seconds [s] before the trajectory.
        stop_policy: what to do on abort, Ctrl-C or the end.
        limp_s: duration of the Goal PWM ramp of a LIMP stop [s].
        hold_s: time to keep streaming the final target after the trajectory ends [s].
        recovery_attempts: automatic recovery attempts per shut-down servo after an abort.
        log_path: CSV log of commanded vs present per cycle (None: no log).
        realtime_priority: run the loop under SCHED_FIFO at this priority (1..99; needs root
            or CAP_SYS_NICE, refused with a warning otherwise); None: normal scheduling.
        cpu_latency_us: while streaming, keep every CPU out of idle states slower to leave
            than this [us] (Linux PM QoS, :func:`drivers.clock.cpu_wakeup_latency`; skipped with
            a note where not permitted); None: CPUs idle freely (less power, later wake-ups).
        expected: where the joints should be over trajectory time (map order): from the
            trajectory's first row on, tracking is watched against it (per-joint tolerance,
            debounced) instead of against ``SafetyLimits.max_tracking_error_rad``. Its times are
            the trajectory's (cycle time times ``speed``, after any approach); each joint's
            distance from it at the first watched cycle (the start, within the start
            tolerance) is added to its tolerance. None: the absolute limit throughout.
        imu: read in every cycle, right after the servos' feedback (the OpenCR shares their bus);
            None: no IMU. A failed read is counted (``ExecutionReport.imu_lost_cycles``), never a
            reason to stop a proven motion half way (stopping mid-rise drops the robot).
        expected_tilt: the torso's expected tilt over trajectory time (times as ``expected``);
            with ``imu``, a torso off it beyond the tolerance is a FALLING fault (the stop policy
            applies). None: the tilt is not watched.
    """

    rate_hz: float = DEFAULT_RATE_HZ
    speed: float = 1.0
    approach_s: float | None = None
    stop_policy: StopPolicy = StopPolicy.HOLD
    limp_s: float = 1.0
    hold_s: float = 0.2
    recovery_attempts: int = 2
    log_path: Path | None = None
    realtime_priority: int | None = None
    cpu_latency_us: int | None = 0
    expected: ExpectedPositions | None = None
    imu: Imu | None = None
    expected_tilt: ExpectedTilt | None = None

    def __post_init__(self) -> None:
        # below MIN_RATE_HZ each step of the velocity limit becomes a jump the servo makes at
        # full speed (4.8 rad/s x 50 ms = 0.24 rad)
        if not MIN_RATE_HZ <= self.rate_hz <= 2000.0:
            raise SafetyError(f"rate {self.rate_hz:g} Hz outside {MIN_RATE_HZ:g}..2000 Hz",
                              hint="the default is 100 Hz; the bus's own limit is checked before streaming")
        if not 0.0 < self.speed <= 2.0:
            raise SafetyError(f"speed {self.speed} outside (0, 2]")
        if self.approach_s is not None and not (self.approach_s > 0 and math.isfinite(self.approach_s)):
            raise SafetyError(f"approach time {self.approach_s} s must be positive")
        if not (self.limp_s > 0 and math.isfinite(self.limp_s)):
            raise SafetyError(f"limp time {self.limp_s} s must be positive")
        if not (0.0 <= self.hold_s < math.inf):
            raise SafetyError(f"hold time {self.hold_s} s must be >= 0")
        if self.recovery_attempts < 0:
            raise SafetyError(f"recovery attempts {self.recovery_attempts} must be >= 0")
        if self.realtime_priority is not None and not 1 <= self.realtime_priority <= 99:
            raise SafetyError(f"real-time priority {self.realtime_priority} outside 1..99")
        if self.cpu_latency_us is not None and self.cpu_latency_us < 0:
            raise SafetyError(f"CPU wake-up latency {self.cpu_latency_us} us must be >= 0")


@dataclass(frozen=True)
class CycleStats:
    """Timing statistics over all cycles.

    Attributes:
        cycles: number of cycles run.
        period_s: nominal period [s].
        jitter_p50_s / jitter_p99_s / jitter_max_s: lateness of cycle starts [s].
        deadline_misses: cycles whose work overran the period.
        work_mean_s / work_max_s: wall time of a cycle's work [s].
        cpu_mean_s: host CPU time per cycle, emulator excluded when measurable [s].
        resyncs: cycles that started more than a period late; the schedule was re-anchored
            there (the trajectory is delayed, never replayed faster than planned).
        wait_cpu_mean_s: CPU time per cycle spent waiting for the cycle's start [s]: the busy
            final stretch of the clock's sleep (:data:`drivers.clock.SPIN_MARGIN_S`), the
            price of the start-time precision; not included in ``cpu_mean_s``.
    """

    cycles: int
    period_s: float
    jitter_p50_s: float
    jitter_p99_s: float
    jitter_max_s: float
    deadline_misses: int
    work_mean_s: float
    work_max_s: float
    cpu_mean_s: float
    resyncs: int = 0
    wait_cpu_mean_s: float = 0.0

    @staticmethod
    def from_samples(period_s: float, lateness: Sequence[float], work: Sequence[float],
                     cpu: Sequence[float], *, resyncs: int = 0,
                     wait_cpu: Sequence[float] = ()) -> "CycleStats":
        if not lateness:
            return CycleStats(0, period_s, 0.0, 0.0, 0.0, 0, 0.0, 0.0, 0.0, resyncs)
        late = np.asarray(lateness)
        w = np.asarray(work)
        return CycleStats(
            cycles=len(late), period_s=period_s,
            jitter_p50_s=float(np.percentile(late, 50)), jitter_p99_s=float(np.percentile(late, 99)),
            jitter_max_s=float(late.max()), deadline_misses=int(np.sum(w > period_s)),
            work_mean_s=float(w.mean()), work_max_s=float(w.max()), cpu_mean_s=float(np.mean(cpu)),
            resyncs=resyncs, wait_cpu_mean_s=float(np.mean(wait_cpu)) if len(wait_cpu) else 0.0,
        )


@dataclass(frozen=True)
class ExecutionReport:
    """Outcome of one execution.

    Attributes:
        completed: the whole trajectory ran without a fault.
        faults: faults that caused the stop (empty if completed).
        stats: :class:`CycleStats`.
        max_tracking_error_rad: largest |present - previous command| seen [rad].
        max_expected_error_rad: largest distance of a present position outside the band from its expected position to its goals (``band_deviation``) [rad] (None: not watched).
        max_expected_ratio: that distance / the tolerance, largest seen (None: not watched;
            above 1 only for fewer cycles in a row than the debounce, or at a fault).
        max_tilt_error_rad: largest |torso tilt - expected tilt| the IMU showed [rad] (None: not
            watched).
        imu_lost_cycles: cycles whose IMU read failed (0 without an IMU).
        clamped_cycles: cycles in which the safety layer changed the target.
        stop_policy: the policy applied at the end.
        recovery: recovery outcome if one was attempted.
        log_path: where the per-cycle log went.
        timing: how the loop ran (scheduling policy, CPU wake-up latency request).
    """

    completed: bool
    faults: tuple[Fault, ...]
    stats: CycleStats
    max_tracking_error_rad: float
    clamped_cycles: int
    stop_policy: StopPolicy
    recovery: RecoveryReport | None = None
    log_path: Path | None = None
    commands: FloatArray | None = field(default=None, repr=False)
    timing: str = ""
    max_expected_error_rad: float | None = None
    max_expected_ratio: float | None = None
    max_tilt_error_rad: float | None = None
    imu_lost_cycles: int = 0

    @property
    def interrupted(self) -> bool:
        return any(f.kind is FaultKind.INTERRUPTED for f in self.faults)


def interpolate(t: FloatArray, q: FloatArray, tau: float) -> FloatArray:
    """Linear interpolation of ``q`` (shape (T, n)) at time ``tau`` [s]; clamped at the ends."""
    if tau <= t[0]:
        return q[0].copy()
    if tau >= t[-1]:
        return q[-1].copy()
    i = int(np.searchsorted(t, tau, side="right"))
    a = (tau - t[i - 1]) / (t[i] - t[i - 1])
    return q[i - 1] + a * (q[i] - q[i - 1])


class Executor:
    """Streams one trajectory to a :class:`ServoGroup` under the safety layer.

    Args:
        group: the engaged servo group (torque on, watchdog armed).
        limits: :class:`SafetyLimits` in map order.
        config: :class:`ExecutorConfig`.
    """

    def __init__(self, group: ServoGroup, limits: SafetyLimits, config: ExecutorConfig | None = None) -> None:
        self.group = group
        self.limits = limits
        self.config = config or ExecutorConfig()
        if len(limits.lower_rad) != len(group.ids):
            raise SafetyError(f"limits for {len(limits.lower_rad)} joints, group has {len(group.ids)}")
        expected = self.config.expected
        if expected is not None and expected.q_rad.shape[1] != len(group.ids):
            raise SafetyError(f"expected positions for {expected.q_rad.shape[1]} joints, group has {len(group.ids)}")

    def prepare(self, joint_names: Sequence[str], t: FloatArray, q: FloatArray,
                q_present: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Map the trajectory onto servo order, check the start, prepend an approach.

        Args:
            joint_names: trajectory columns.
            t: sample times [s], shape (T,), increasing.
            q: joint angles [rad], shape (T, len(joint_names)).
            q_present: present posture in map order [rad], shape (n,).

        Returns:
            (t [s] shape (T',), q [rad] shape (T', n)) in map order, time-scaled by ``speed``.

        Raises:
            SafetyError: bad shapes, a joint outside its limits at present, or the start is far
                from the present posture and no approach was requested.
        """
        wire_s = self.group.cycle_wire_time_s()
        if self.config.rate_hz * wire_s > 1.0:
            raise SafetyError(
                f"rate {self.config.rate_hz:g} Hz is more than the bus allows: one cycle of {len(self.group.ids)} "
                f"servos takes {wire_s * 1e3:.2f} ms on the wire at {self.group.bus.baud_rate} bit/s "
                f"(at most {1.0 / wire_s:.0f} Hz)",
                hint="lower --rate, or raise the bus baud rate (servos.toml and the servos' Baud Rate)")
        t = np.asarray(t, dtype=float)
        q = np.asarray(q, dtype=float)
        if t.ndim != 1 or q.ndim != 2 or q.shape != (t.size, len(joint_names)) or t.size < 1:
            raise SafetyError(f"trajectory shapes t{t.shape} q{q.shape} do not match {len(joint_names)} joints")
        if t.size > 1 and np.any(np.diff(t) <= 0):
            raise SafetyError("trajectory times must increase strictly")
        if not np.all(np.isfinite(q)):
            raise SafetyError("trajectory contains NaN or infinite angles")
        require_inside_limits(q_present, self.limits.lower_rad, self.limits.upper_rad,
                              [sp.label for sp in self.group.map.servos], "not streaming")
        idx = self.group.map.index_of(joint_names)
        qm = q[:, idx]
        tm = (t - t[0]) / self.config.speed
        start = check_start(qm[0], q_present, self.limits)
        if self.config.approach_s is None:
            if not start.ok:
                name = self.group.map.servos[start.worst_index].joint
                raise SafetyError(
                    f"first target is {start.max_error_rad:.3f} rad from the present posture at {name} "
                    f"(tolerance {self.limits.start_tolerance_rad} rad)",
                    hint=f"request a slow approach (--approach {max(2.0, math.ceil(start.min_approach_s * 2)):.0f})"
                         " or pose the robot at the trajectory's start")
        # from where the joints are, clamped into the limits (a joint resting on its stop reads a hair
        # past it, within the tolerance accepted above): the approach itself never needs a clamp
        inside = np.clip(np.asarray(q_present, dtype=float), self.limits.lower_rad, self.limits.upper_rad)
        if self.config.approach_s is None:
            if float(np.max(np.abs(qm[0] - inside), initial=0.0)) <= self.limits.max_step_rad(1.0 / self.config.rate_hz):
                return tm, qm
            # within the start tolerance but more than one cycle's step away (a body settled a little
            # off the trajectory's start): the shortest approach the approach velocity allows, so the
            # first command is not a step the safety layer has to clamp
            ta, qa = approach_path(inside, qm[0], 0.0, self.limits)
            return np.concatenate([ta, ta[-1] + 0.01 + tm]), np.vstack([qa, qm])
        ta, qa = approach_path(inside, qm[0], self.config.approach_s, self.limits)
        return np.concatenate([ta, ta[-1] + 0.01 + tm]), np.vstack([qa, qm])

    def run(self, joint_names: Sequence[str], t: FloatArray, q: FloatArray) -> ExecutionReport:
        """Execute; returns a report (faults, bus and host errors in the loop included, are
        reported, not raised; a refused start raises :class:`SafetyError` before anything moves)."""
        # a simulated clock has no wake-ups to make punctual
        latency_us = self.config.cpu_latency_us if isinstance(self.group.bus.clock, MonotonicClock) else None
        with realtime_scheduling(self.config.realtime_priority) as sched, cpu_wakeup_latency(latency_us) as idle:
            _log.info("executor: %s; %s", sched, idle)
            return replace(self._run(joint_names, t, q), timing=f"{sched}; {idle}")

    def _run(self, joint_names: Sequence[str], t: FloatArray, q: FloatArray) -> ExecutionReport:
        cfg, group, limits = self.config, self.group, self.limits
        clock = group.bus.clock
        fb0 = group.read_feedback()
        if not fb0.valid.all():
            missing = [sid for sid, ok in zip(group.ids, fb0.valid) if not ok]
            raise SafetyError(f"no present position from servo(s) {missing}; refusing to start")
        t_run, q_run = self.prepare(joint_names, t, q, fb0.position_rad)
        # the trajectory's first row starts after any approach; expected positions are watched from there
        t_first = float(t_run[len(t_run) - np.asarray(t).size])
        expected = cfg.expected
        tolerance: FloatArray | None = None  # expected.tolerance_rad + each joint's offset at the start
        beyond = np.zeros(len(group.ids), dtype=np.int64)
        max_expected = max_ratio = 0.0
        tilt_beyond = imu_lost = 0
        max_tilt: float | None = None
        watchdog_s = self._armed_watchdog_s()
        pwm_limits = self._pwm_limits()
        dt = 1.0 / cfg.rate_hz
        t_end = float(t_run[-1]) + cfg.hold_s
        n_cycles = int(math.floor(t_end / dt)) + 1
        # a clamped command may still be catching up at the end: keep streaming until it has
        # reached the final target, within at most the time the step limit needs (+1 s)
        q_final = np.clip(q_run[-1], limits.lower_rad, limits.upper_rad)
        span = float(np.max(limits.upper_rad - limits.lower_rad))
        max_cycles = n_cycles + int(math.ceil((span / limits.max_velocity_rad_s + 1.0) / dt))
        port = group.bus.port
        log = _CycleLog(cfg.log_path, group.map.joint_names) if cfg.log_path else None
        lateness: list[float] = []
        work: list[float] = []
        cpu: list[float] = []
        wait_cpu: list[float] = []
        q_prev = np.clip(fb0.position_rad, limits.lower_rad, limits.upper_rad)
        q_tracked = fb0.position_rad.copy()  # what the servos were last told (for tracking error)
        commands: list[FloatArray] = []
        faults: list[Fault] = []
        max_track = 0.0
        clamped_cycles = 0
        last_fb: Feedback = fb0
        k = 0
        resyncs = 0
        t0 = clock.now()
        t_origin = last_sent = t0
        try:
            for k in range(max_cycles):
                t_nominal = t0 + k * dt
                now = clock.now()
                w0 = time.thread_time()
                if now < t_nominal:
                    clock.sleep(t_nominal - now)
                wait_cpu.append(time.thread_time() - w0)
                start = clock.now()
                lateness.append(start - t_nominal)
                if watchdog_s is not None and start - last_sent > watchdog_s:
                    faults = [Fault(FaultKind.DEADLINE, -1, start - last_sent, watchdog_s,
                                    f"host stalled {(start - last_sent) * 1e3:.0f} ms, longer than the "
                                    f"{watchdog_s * 1e3:.0f} ms Bus Watchdog: the servos stopped themselves")]
                    _log.error("abort: %s", faults[0].message)
                    break
                if start - t_nominal > dt:
                    # a stall (host or bus) cost whole periods: re-anchor the schedule instead of
                    # running the missed cycles back to back, which would move the servos faster
                    # than the per-cycle step limit allows; the motion is delayed, never hurried
                    t0 += start - t_nominal
                    resyncs += 1
                c0 = time.thread_time()
                e0 = getattr(port, "emulator_time_s", 0.0)
                q_des = interpolate(t_run, q_run, k * dt)
                q_cmd, clamped = safe_target(q_des, q_prev, limits, dt)
                clamped_cycles += clamped
                group.write_goals(q_cmd, defer=True)  # leaves with the feedback read
                last_sent = clock.now()  # the watchdogs are fed when these packets arrive
                fb = group.read_feedback()
                for sid in group.readmitted:  # back from quarantine: restart from where it is
                    j = group.ids.index(sid)
                    if fb.valid[j]:
                        q_cmd[j] = float(np.clip(fb.position_rad[j], limits.lower_rad[j], limits.upper_rad[j]))
                commands.append(q_cmd)
                tau = (k * dt - t_first) * cfg.speed  # trajectory time of this cycle
                watched = expected if expected is not None and tau >= -1e-9 else None
                found = evaluate_feedback(
                    limits, q_command_rad=q_tracked if watched is None else None, q_present_rad=fb.position_rad,
                    valid=fb.valid, hardware_error=fb.alert, temperature_c=fb.temperature_c,
                    voltage_v=fb.voltage_v, consecutive_failures=group.consecutive_failures)
                if watched is not None:
                    q_expected = interpolate(watched.t_s, watched.q_rad, tau)
                    err = band_deviation(fb.position_rad, q_expected, q_tracked, q_cmd)
                    if tolerance is None:  # a start within the start tolerance is accepted as it is
                        tolerance = watched.tolerance_rad + np.where(fb.valid, err, 0.0)
                    beyond, off = evaluate_expected(fb.position_rad, q_expected, tolerance, fb.valid, beyond,
                                                    watched.debounce_cycles(dt), (q_tracked, q_cmd))
                    found = [*found, *off]
                    if fb.valid.any():
                        max_expected = max(max_expected, float(np.max(err[fb.valid])))
                        max_ratio = max(max_ratio, float(np.max((err / tolerance)[fb.valid])))
                if cfg.imu is not None:
                    sample = cfg.imu.read()
                    if not sample.valid:
                        imu_lost += 1
                    elif cfg.expected_tilt is not None and tau >= -1e-9:
                        tilt, should = sample.tilt_rad, cfg.expected_tilt.at(tau)
                        tilt_beyond, falling = evaluate_tilt(tilt, should, cfg.expected_tilt.tolerance_rad, tilt_beyond,
                                                             cfg.expected_tilt.debounce_cycles(dt))
                        found = [*found, *falling]
                        if math.isfinite(tilt):
                            max_tilt = max(max_tilt or 0.0, abs(tilt - should))
                if fb.valid.all():
                    max_track = max(max_track, float(np.max(np.abs(fb.position_rad - q_tracked))))
                elif fb.valid.any():
                    max_track = max(max_track, float(np.max(np.abs(fb.position_rad - q_tracked)[fb.valid])))
                if log:
                    log.row(k, start - t_origin, q_cmd, fb)  # wall time: stalls show
                q_prev, q_tracked, last_fb = q_cmd, q_cmd, fb
                cpu.append(time.thread_time() - c0 - (getattr(port, "emulator_time_s", 0.0) - e0))
                work.append(clock.now() - start)
                if found:
                    faults = found
                    for f in found:
                        _log.error("abort: %s", f.message)
                    break
                if k + 1 >= n_cycles and float(np.max(np.abs(q_cmd - q_final))) < 1e-9:
                    break
        except KeyboardInterrupt:
            faults = [Fault(FaultKind.INTERRUPTED, -1, 0, 0, "interrupted by the operator")]
            _log.warning("interrupted: stopping by policy %s", cfg.stop_policy.value)
        except CommunicationError as e:  # the port itself failed (unplugged adapter, write timeout)
            faults = [Fault(FaultKind.COMMUNICATION, -1, 0, 0, f"bus: {e}")]
            _log.error("abort: %s", faults[0].message)
        except Exception as e:  # noqa: BLE001 - a host error must still end in a controlled stop
            faults = [Fault(FaultKind.HOST, -1, 0, 0, f"host error in the control loop: {type(e).__name__}: {e}")]
            _log.exception("abort: %s", faults[0].message)
        hold = q_prev if not faults and commands else None  # a normal end holds the final command
        recovery, problems = self._stop(last_fb, faults, pwm_limits, watchdog_s, hold)
        faults = [*faults, *(Fault(FaultKind.COMMUNICATION, -1, 0, 0, text) for text in problems)]
        if log:  # after the stop: a failing disk must not delay it
            try:
                log.close()
            except OSError as e:
                faults.append(Fault(FaultKind.HOST, -1, 0, 0, f"the cycle log {cfg.log_path} is incomplete: {e}"))
        stats = CycleStats.from_samples(dt, lateness, work, cpu, resyncs=resyncs, wait_cpu=wait_cpu)
        if resyncs:
            _log.warning("%d stall(s) longer than a period: schedule re-anchored, motion delayed", resyncs)
        watched_any = tolerance is not None
        return ExecutionReport(not faults, tuple(faults), stats, max_track, clamped_cycles,
                               cfg.stop_policy, recovery, cfg.log_path,
                               np.array(commands) if commands else None,
                               max_expected_error_rad=max_expected if watched_any else None,
                               max_expected_ratio=max_ratio if watched_any else None,
                               max_tilt_error_rad=max_tilt, imu_lost_cycles=imu_lost)

    def _armed_watchdog_s(self) -> float | None:
        """The Bus Watchdog timeout the servos have armed [s] (the shortest), None if none is.

        Read from the servos, not configured: with it the rate must feed the watchdog at least
        twice per timeout, and a host stall longer than it is a DEADLINE fault.

        Raises:
            SafetyError: a watchdog has tripped (the servo refuses goals), or the rate is too low.
        """
        if not self.group.has_watchdog:  # Protocol 1.0: the host stops the servos itself
            return None
        units = self.group.read_each("bus_watchdog")
        tripped = sorted(sid for sid, u in units.items() if u < 0)
        if tripped:
            raise SafetyError(f"the Bus Watchdog of servo(s) {tripped} has tripped: they refuse goal positions",
                              hint="engage the servos again (robot-rise servos torque on, or execute does it)")
        armed = [u for u in units.values() if u > 0]
        if not armed:
            return None
        timeout_s = min(armed) * WATCHDOG_UNIT_S
        if 2.0 / self.config.rate_hz > timeout_s:
            raise SafetyError(f"rate {self.config.rate_hz:g} Hz feeds the {timeout_s * 1e3:.0f} ms Bus Watchdog "
                              f"less than twice per timeout; the servos would stop themselves",
                              hint=f"use a rate of at least {math.ceil(2.0 / timeout_s):.0f} Hz")
        return timeout_s

    def _pwm_limits(self) -> dict[int, int]:
        """Each servo's PWM Limit (the Goal PWM the RAM settings gave it; on 1.0 its Torque
        Limit): the LIMP ramp's start. A servo that does not answer now gets its model's default."""
        name = self.group.ramp_limit_register
        read = self.group.read_each(name)
        return {sp.id: read.get(sp.id, int(sp.table.defaults.get(name, 0))) for sp in self.group.map.servos}

    def _stop(self, fb: Feedback, faults: list[Fault], pwm_limits: dict[int, int], watchdog_s: float | None,
              hold_rad: FloatArray | None = None) -> tuple[RecoveryReport | None, list[str]]:
        """Controlled stop by policy; never a jump: the targets are the present positions, or at a
        normal end ``hold_rad``, the final command (the goal the servos already track: goal =
        present would let a loaded joint sag by its position loop's steady-state error).

        Every step is attempted even if one fails (a failed write is reported, the next step
        still runs; torque off always closes a LIMP stop), and a Ctrl-C during the stop does not
        cut it short. Returns the recovery report and what failed.
        """
        group, cfg = self.group, self.config
        clock = group.bus.clock
        dt = 1.0 / cfg.rate_hz
        problems: list[str] = []

        def step(what: str, action: Callable[[], object]) -> None:
            for _ in range(2):  # a second Ctrl-C must not cut the stop short: the step is retried
                try:
                    action()
                    return
                except CommunicationError as e:
                    _log.error("stop: %s failed: %s", what, e)
                    problems.append(f"stop: {what} failed: {e}")
                    return
                except KeyboardInterrupt:
                    _log.warning("stop in progress (%s): Ctrl-C ignored until the robot is stopped", what)

        limp = cfg.stop_policy is StopPolicy.LIMP
        # a tripped Bus Watchdog refuses goal and PWM writes: clear it first; a LIMP ramp keeps it
        # armed, so the servos still stop themselves if the host dies during the ramp
        if limp and watchdog_s is not None:
            step("re-arming the Bus Watchdog", lambda: arm_watchdog(group, watchdog_s))
        else:
            step("clearing the Bus Watchdog", lambda: disarm_watchdog(group))
        try:
            now_fb = group.read_feedback()
        except (Exception, KeyboardInterrupt):  # noqa: BLE001 - stopping must go on with what we have
            now_fb = fb
        hold = np.where(now_fb.valid, now_fb.position_rad, fb.position_rad) if hold_rad is None else hold_rad
        # a joint the body pushed past its stop reads a tick beyond the limit: the hold goal must not follow it
        hold = np.clip(hold, self.limits.lower_rad, self.limits.upper_rad)
        ok = np.isfinite(hold)
        skip = [sid for sid, good in zip(group.ids, ok) if not good]
        step("holding the present posture", lambda: group.write_goals(np.where(ok, hold, 0.0), skip=skip))
        if limp:
            ids = list(pwm_limits)
            ramp = group.ramp_register  # Goal PWM (2.0) or Torque Limit (1.0)
            try:
                for row in limp_pwm_ramp(np.array([pwm_limits[sid] for sid in ids]), cfg.limp_s, dt):
                    step("the Goal PWM ramp", lambda row=row: group.write_each(
                        ramp.address, ramp.size, dict(zip(ids, row)), quarantined_too=True))
                    step("the Goal PWM ramp", lambda: clock.sleep(dt))
            finally:
                step("torque off", lambda: group.torque(False, quarantined_too=True))
                step("disarming the Bus Watchdog", lambda: disarm_watchdog(group))
            return None, problems
        shut = [sid for sid, bits in zip(group.ids, now_fb.hardware_error) if bits]
        # the Bus Watchdog was disarmed above: streaming is over and every servo holds; recovery
        # (reboot + boot wait of one servo) would starve the others' watchdogs and trip them
        recovery = None
        if faults and shut and cfg.recovery_attempts > 0:
            _log.warning("attempting recovery of servo(s) %s", shut)
            try:
                recovery = recover(group, shut, attempts=cfg.recovery_attempts)
            except CommunicationError as e:
                problems.append(f"stop: recovery failed: {e}")
        return recovery, problems


class _CycleLog:
    """CSV: cycle, t [s], then cmd_<joint> [rad], pos_<joint> [rad], then error bytes."""

    def __init__(self, path: Path, joints: Sequence[str]) -> None:
        self._f: IO[str] = open(path, "w", encoding="utf-8")
        cols = ["cycle", "t_s"] + [f"cmd_{j}" for j in joints] + [f"pos_{j}" for j in joints] + \
               [f"err_{j}" for j in joints]
        self._f.write(",".join(cols) + "\n")

    def row(self, k: int, t: float, q_cmd: FloatArray, fb: Feedback) -> None:
        parts = [str(k), f"{t:.6f}"]
        parts += [f"{v:.5f}" for v in q_cmd]
        parts += ["" if not np.isfinite(v) else f"{v:.5f}" for v in fb.position_rad]
        parts += [str(int(e)) for e in fb.alert]
        self._f.write(",".join(parts) + "\n")

    def close(self) -> None:
        self._f.close()
