"""The streaming executor on the emulator, nominal and under scripted faults.

Every test checks, at byte level, that no goal position ever sent left the joint limits or
moved more than the per-cycle step limit (:func:`_assert_goals_safe`).
"""

from __future__ import annotations

import math
import re
from pathlib import Path
import struct

import numpy as np
import pytest

from drivers.control_table import RAD_PER_TICK, HardwareErrorBits
from drivers.errors import SafetyError
from drivers.executor import Executor, ExecutorConfig, interpolate
from drivers.protocol import Instruction
from drivers.safety import FaultKind, SafetyLimits, StopPolicy
from drivers.servo_map import ServoMap
from drivers.startup import engage, preflight
from hil_tests.conftest import Rig, make_rig

RATE = 100.0
MAX_V = 3.0  # rad/s


def _trajectory(servo_map: ServoMap, *, amplitude: float = 0.4, duration: float = 1.0):
    t = np.linspace(0.0, duration, 11)
    goal = np.clip(np.full(len(servo_map), amplitude), servo_map.lower_rad, servo_map.upper_rad)
    q = (t / duration)[:, None] * goal[None, :]
    return servo_map.joint_names, t, q


def _ready(servo_map: ServoMap, **kw: object) -> Rig:
    r = make_rig(servo_map, **kw)
    _COMPLETED.pop(id(r), None)  # a fresh rig may reuse an old one's id
    preflight(r.group)
    engage(r.group, watchdog_s=0.1)
    return r


_COMPLETED: dict[int, bool] = {}


def _run(r: Rig, traj=None, **cfg: object):
    limits = r.limits(max_velocity_rad_s=MAX_V)
    ex = Executor(r.group, limits, ExecutorConfig(rate_hz=RATE, **cfg))  # type: ignore[arg-type]
    names, t, q = traj or _trajectory(r.servo_map)
    rep = ex.run(names, t, q)
    _COMPLETED[id(r)] = rep.completed
    return rep


def _goal_writes(r: Rig) -> list[dict[int, int]]:
    out = []
    for p in r.mock.log:
        if p.instruction == Instruction.SYNC_WRITE and struct.unpack_from("<H", p.params)[0] == 116:
            body = p.params[4:]
            out.append({body[k]: struct.unpack_from("<i", body, k + 1)[0] for k in range(0, len(body), 5)})
    return out


def _assert_goals_safe(r: Rig, rate: float = RATE) -> None:
    """Every goal inside the limits; every streamed goal within one step of the previous one.

    The final write of a stop after a fault is goal = present position, which may differ from
    the last command by the tracking lag; at a normal end it is the last command again. It is
    checked against both.
    """
    step_ticks = math.ceil(MAX_V / rate / RAD_PER_TICK) + 1
    last: dict[int, int] = {}
    writes = _goal_writes(r)
    streamed = writes[-2] if len(writes) > 1 else {}
    completed = _COMPLETED.get(id(r))  # the outcome _run saw, if it ran this rig
    for sid, tick in writes[-1].items():
        lo, hi = r.servo_map.by_id(sid).limit_ticks
        assert lo <= tick <= hi
        at_present = abs(tick - r.mock.servo(sid).get("present_position")) <= 3
        if completed is None:
            assert at_present or tick == streamed.get(sid)
        else:
            assert tick == streamed.get(sid) if completed else at_present
    for sid, tick in ((s, t) for w in writes[:-1] for s, t in w.items()):
        lo, hi = r.servo_map.by_id(sid).limit_ticks
        assert lo <= tick <= hi, f"servo {sid}: goal {tick} outside {lo}..{hi}"
        if sid in last:
            assert abs(tick - last[sid]) <= step_ticks, f"servo {sid}: step {tick - last[sid]} ticks"
        last[sid] = tick


def _interrupt(bus) -> None:
    """A scheduled fault: the operator presses Ctrl-C."""
    raise KeyboardInterrupt


def test_that_interpolation_is_linear_and_clamped_at_the_ends() -> None:
    t = np.array([0.0, 1.0])
    q = np.array([[0.0], [2.0]])
    assert interpolate(t, q, 0.25)[0] == pytest.approx(0.5)
    assert interpolate(t, q, -1)[0] == 0.0 and interpolate(t, q, 5)[0] == 2.0


def test_that_a_nominal_trajectory_runs_to_the_end_and_logs_each_cycle(servo_map: ServoMap, tmp_path) -> None:
    r = _ready(servo_map)
    log = tmp_path / "run.csv"
    rep = _run(r, log_path=log)
    assert rep.completed and rep.faults == ()
    assert rep.stats.cycles == int(1.2 * RATE) + 1
    assert rep.max_tracking_error_rad < 0.1
    lines = log.read_text().splitlines()
    assert lines[0].startswith("cycle,t_s,cmd_r_sho_pitch") and len(lines) == rep.stats.cycles + 1
    fb = r.group.read_feedback()
    goal = np.clip(np.full(20, 0.4), servo_map.lower_rad, servo_map.upper_rad)
    assert np.allclose(fb.position_rad, goal, atol=0.01)
    _assert_goals_safe(r)


def test_that_speed_scales_trajectory_time(servo_map: ServoMap) -> None:
    rep = _run(_ready(servo_map), speed=0.5)
    assert rep.completed and rep.stats.cycles == int(2.2 * RATE) + 1


def test_that_a_far_start_is_refused_without_approach(servo_map: ServoMap) -> None:
    r = _ready(servo_map)
    names, t, q = _trajectory(servo_map)
    q = q + 0.3
    with pytest.raises(SafetyError, match="from the present posture") as e:
        _run(r, (names, t, q))
    assert "--approach" in e.value.hint
    assert _goal_writes(r) == [] or all(len(w) == 20 for w in _goal_writes(r))


def test_that_an_approach_moves_slowly_from_the_present_posture(servo_map: ServoMap) -> None:
    r = _ready(servo_map)
    names, t, q = _trajectory(servo_map)
    q = np.clip(q + 0.3, servo_map.lower_rad, servo_map.upper_rad)
    rep = _run(r, (names, t, q), approach_s=1.0)
    assert rep.completed
    _assert_goals_safe(r)


def test_that_an_unsafe_trajectory_is_clamped_in_limits_and_step(servo_map: ServoMap) -> None:
    r = _ready(servo_map)
    names = servo_map.joint_names
    t = np.array([0.0, 0.01, 0.5, 0.51])
    q = np.zeros((4, 20))
    q[1:3] = 5.0  # far outside limits and far too fast
    rep = _run(r, (names, t, q), )
    assert rep.clamped_cycles > 0
    _assert_goals_safe(r)


@pytest.mark.parametrize(
    ("fault", "kind"),
    [
        (lambda bus: bus.faults.hardware_error(5, HardwareErrorBits.OVERLOAD), FaultKind.HARDWARE),
        (lambda bus: bus.faults.silence(11), FaultKind.COMMUNICATION),
        (lambda bus: setattr(bus.faults, "heating_gain", 3e4), FaultKind.TEMPERATURE),
        (lambda bus: setattr(bus.faults, "input_voltage_v", 9.0), FaultKind.VOLTAGE),
        (lambda bus: setattr(bus.faults, "input_voltage_v", 15.5), FaultKind.VOLTAGE),
        (lambda bus: bus.faults.hardware_error(14, HardwareErrorBits.ELECTRICAL_SHOCK), FaultKind.HARDWARE),
        (lambda bus: bus.faults.deaf_ids.add(17), FaultKind.COMMUNICATION),
    ],
    ids=["overload", "silent-servo", "overheating", "undervoltage", "overvoltage", "electrical-shock", "deaf-servo"],
)
def test_that_each_fault_stops_the_run_safely_and_is_reported(servo_map: ServoMap, fault, kind) -> None:
    r = _ready(servo_map)
    r.mock.faults.at(r.clock.now() + 0.4, fault)
    rep = _run(r)
    assert not rep.completed and kind in {f.kind for f in rep.faults}
    assert 0.35 * RATE < rep.stats.cycles < 0.6 * RATE
    _assert_goals_safe(r)
    # HOLD: the last goal is the present position of each answering servo (no jump)
    last = _goal_writes(r)[-1]
    for sid, tick in last.items():
        emu = r.mock.servo(sid)
        assert abs(tick - emu.get("present_position")) <= 3


def test_that_recovery_brings_a_shut_down_servo_back_to_holding(servo_map: ServoMap) -> None:
    r = _ready(servo_map)
    r.mock.faults.at(r.clock.now() + 0.3, lambda bus: bus.faults.hardware_error(5, HardwareErrorBits.OVERLOAD))
    rep = _run(r)
    assert rep.recovery is not None and rep.recovery.recovered == (5,)
    assert r.mock.servo(5).torque_on


def test_that_occasional_corrupt_replies_do_not_abort_the_run(servo_map: ServoMap) -> None:
    r = _ready(servo_map)
    r.mock.faults.corrupt_probability = 0.02
    rep = _run(r)
    assert rep.completed, rep.faults
    _assert_goals_safe(r)


def test_that_ctrl_c_stops_by_policy_and_is_reported(servo_map: ServoMap) -> None:
    r = _ready(servo_map)

    r.mock.faults.at(r.clock.now() + 0.25, _interrupt)
    rep = _run(r)
    assert rep.interrupted and not rep.completed
    _assert_goals_safe(r)


def test_that_limp_policy_ramps_pwm_down_then_turns_torque_off(servo_map: ServoMap) -> None:
    r = _ready(servo_map)
    r.mock.faults.at(r.clock.now() + 0.3, lambda bus: bus.faults.silence(2))
    rep = _run(r, stop_policy=StopPolicy.LIMP, limp_s=0.5)
    assert not rep.completed
    pwm = [struct.unpack_from("<h", p.params, 5)[0] for p in r.mock.log
           if p.instruction == Instruction.SYNC_WRITE and struct.unpack_from("<H", p.params)[0] == 100]
    assert len(pwm) == 50 and pwm == sorted(pwm, reverse=True) and pwm[-1] == 0
    assert not any(r.mock.servo(s).torque_on for s in servo_map.ids if s != 2)


def test_that_a_dead_host_trips_the_servo_watchdog(servo_map: ServoMap) -> None:
    r = _ready(servo_map)

    def host_dies(bus):
        raise SystemExit("host died")

    r.mock.faults.at(r.clock.now() + 0.3, host_dies)
    with pytest.raises(SystemExit):
        _run(r)
    r.clock.sleep(0.15)
    r.mock.advance()
    for sid in servo_map.ids:
        emu = r.mock.servo(sid)
        assert emu.get("bus_watchdog") == -1
        assert abs(emu.get("goal_position") - emu.get("present_position")) <= 3


def test_that_timing_stats_see_slow_replies(servo_map: ServoMap) -> None:
    r = _ready(servo_map)
    r.mock.faults.at(r.clock.now() + 0.2, lambda bus: setattr(bus.faults, "extra_latency_s", 0.003))
    rep = _run(r)
    assert rep.completed and rep.stats.work_max_s >= 0.003 and rep.stats.deadline_misses == 0


def test_that_a_stall_delays_the_motion_instead_of_replaying_missed_cycles_fast(servo_map: ServoMap) -> None:
    r = _ready(servo_map)
    stall_at = r.clock.now() + 0.3
    r.mock.faults.at(stall_at, lambda bus: bus.clock.advance(0.05))  # type: ignore[attr-defined]
    rep = _run(r)
    assert rep.completed, rep.faults
    assert rep.stats.resyncs == 1
    assert rep.stats.jitter_max_s >= 0.03  # the stall hit mid-cycle: the next start is late
    assert rep.stats.jitter_p50_s < 0.001  # after the stall the schedule is back on its period
    _assert_goals_safe(r)


@pytest.mark.parametrize("fault", ["drop_probability", "truncate_probability"])
def test_that_lost_or_cut_replies_never_lead_to_an_unsafe_goal(servo_map: ServoMap, fault: str) -> None:
    r = _ready(servo_map)
    setattr(r.mock.faults, fault, 0.05)
    rep = _run(r)
    # a few lost cycles are tolerated (quarantine, re-ping); a run of them is a fault
    assert rep.completed or {f.kind for f in rep.faults} == {FaultKind.COMMUNICATION}
    _assert_goals_safe(r)


def test_that_ctrl_c_under_the_limp_policy_ramps_down_and_turns_torque_off(servo_map: ServoMap) -> None:
    r = _ready(servo_map)

    r.mock.faults.at(r.clock.now() + 0.25, _interrupt)
    rep = _run(r, stop_policy=StopPolicy.LIMP, limp_s=0.3)
    assert rep.interrupted
    assert not any(r.mock.servo(s).torque_on for s in servo_map.ids)
    _assert_goals_safe(r)


def test_that_recovering_one_servo_does_not_trip_the_others_watchdog(servo_map: ServoMap) -> None:
    r = _ready(servo_map)
    r.mock.faults.at(r.clock.now() + 0.3, lambda bus: bus.faults.hardware_error(5, HardwareErrorBits.OVERLOAD))
    rep = _run(r, recovery_attempts=2)
    assert rep.recovery is not None and rep.recovery.ok
    r.mock.advance()
    assert [s for s in servo_map.ids if r.mock.servo(s).watchdog_trips] == []
    assert all(r.mock.servo(s).torque_on for s in servo_map.ids)  # holding, all of them


def test_that_a_blocked_joint_aborts_on_tracking_error_and_holds(servo_map: ServoMap) -> None:
    r = _ready(servo_map)
    r.mock.faults.at(r.clock.now() + 0.2, lambda bus: bus.faults.block(9))
    rep = _run(r, _trajectory(servo_map, amplitude=1.0))
    assert not rep.completed
    tracking = [f for f in rep.faults if f.kind is FaultKind.TRACKING]
    assert tracking and {f.index for f in tracking} == {servo_map.ids.index(9)}
    assert rep.max_tracking_error_rad > 0.35
    _assert_goals_safe(r)


def test_that_a_second_ctrl_c_does_not_cut_the_limp_ramp_short(servo_map: ServoMap) -> None:
    r = _ready(servo_map)

    r.mock.faults.at(r.clock.now() + 0.25, _interrupt)
    r.mock.faults.at(r.clock.now() + 0.45, _interrupt)  # during the 0.5 s ramp
    rep = _run(r, stop_policy=StopPolicy.LIMP, limp_s=0.5)
    assert rep.interrupted
    pwm = [struct.unpack_from("<h", p.params, 5)[0] for p in r.mock.log
           if p.instruction == Instruction.SYNC_WRITE and struct.unpack_from("<H", p.params)[0] == 100]
    assert len(pwm) >= 48 and pwm == sorted(pwm, reverse=True) and pwm[-1] == 0
    assert not any(r.mock.servo(s).torque_on for s in servo_map.ids)


def test_that_a_rate_above_what_the_wire_allows_is_refused_before_streaming(servo_map: ServoMap) -> None:
    r = _ready(servo_map)
    wire = r.group.cycle_wire_time_s()
    delays = 20 * servo_map.bus.return_delay_time_us * 1e-6
    assert wire == pytest.approx((114 + 34 + 368) * 10 / servo_map.bus.baud_rate + delays)  # fast read
    writes = len(_goal_writes(r))
    ex = Executor(r.group, r.limits(), ExecutorConfig(rate_hz=500.0))
    with pytest.raises(SafetyError, match=rf"more than the bus allows: .* \(at most {1 / wire:.0f} Hz\)"):
        ex.run(*_trajectory(servo_map))
    assert len(_goal_writes(r)) == writes  # nothing streamed
    r.group.fast_read = False  # plain sync read: 20 status packets, a slower cycle
    assert r.group.cycle_wire_time_s() > wire


def test_that_streaming_on_a_real_clock_holds_the_cpu_wake_up_latency(servo_map: ServoMap,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    import contextlib

    import drivers.executor as executor_module
    from drivers.clock import MonotonicClock

    requests: list[int | None] = []

    @contextlib.contextmanager
    def record(max_us: int | None):
        requests.append(max_us)
        yield f"request {max_us}"

    monkeypatch.setattr(executor_module, "cpu_wakeup_latency", record)
    simulated = _run(_ready(servo_map))
    assert requests == [None] and simulated.timing == "normal scheduling; request None"
    real = _ready(servo_map)
    real.group.bus.clock = MonotonicClock()  # the loop's waits are real; the replies stay instant
    rep = _run(real, _trajectory(servo_map, amplitude=0.0, duration=0.1))  # servos at rest: mock time is frozen
    assert requests == [None, 0] and rep.completed and rep.timing.endswith("request 0")
    _run(real, _trajectory(servo_map, amplitude=0.0, duration=0.1), cpu_latency_us=None)
    assert requests[-1] is None


def _pwm_accepted(r: Rig) -> list[int]:
    return [r.mock.servo(s).get("goal_pwm") for s in r.servo_map.ids]


def test_that_a_joint_outside_its_limits_is_refused_before_anything_moves(servo_map: ServoMap) -> None:
    r = _ready(servo_map)
    ex = Executor(r.group, r.limits(max_velocity_rad_s=MAX_V), ExecutorConfig(rate_hz=RATE, approach_s=2.0))
    names, t, q = _trajectory(servo_map)
    present = np.zeros(len(servo_map))
    present[3] = servo_map.upper_rad[3] + 0.3  # posed by hand past its limit
    with pytest.raises(SafetyError, match=rf"{servo_map.servos[3].joint} \(id {servo_map.servos[3].id}\) at .* is 0.300 rad outside its limits"):
        ex.prepare(names, t, q, present)
    present[3] = servo_map.upper_rad[3] + 0.01  # within the tolerance: accepted, then clamped
    ex.prepare(names, t, q, present)


def test_that_a_limp_stop_after_a_watchdog_trip_still_ramps_the_servos_down(servo_map: ServoMap) -> None:
    r = _ready(servo_map)  # watchdog armed at 0.1 s
    r.mock.faults.at(r.clock.now() + 0.5, lambda bus: bus.clock.advance(0.25))  # the host stalls
    rep = _run(r, _trajectory(servo_map, amplitude=0.6, duration=2.0),
               stop_policy=StopPolicy.LIMP, limp_s=0.5)
    assert [f.kind for f in rep.faults] == [FaultKind.DEADLINE] and "Bus Watchdog" in rep.faults[0].message
    # the servos accepted the ramp (a tripped watchdog refuses Goal PWM): it ended at 0, slowly
    assert _pwm_accepted(r) == [0] * len(servo_map)
    assert not any(r.mock.servo(s).torque_on for s in servo_map.ids)
    assert all(r.mock.servo(s).get("bus_watchdog") == 0 for s in servo_map.ids)


@pytest.mark.parametrize("error, kind", [(OSError("adapter unplugged"), FaultKind.COMMUNICATION),
                                         (RuntimeError("a bug"), FaultKind.HOST)])
def test_that_an_error_in_the_loop_ends_in_the_policy_stop_and_is_reported(
        servo_map: ServoMap, error: Exception, kind: FaultKind) -> None:
    r = _ready(servo_map)

    def fail(bus) -> None:
        raise error

    r.mock.faults.at(r.clock.now() + 0.3, fail)
    rep = _run(r, stop_policy=StopPolicy.LIMP, limp_s=0.3)
    assert not rep.completed and [f.kind for f in rep.faults] == [kind] and str(error) in rep.faults[0].message
    assert _pwm_accepted(r) == [0] * len(servo_map)
    assert not any(r.mock.servo(s).torque_on for s in servo_map.ids)
    assert all(r.mock.servo(s).get("bus_watchdog") == 0 for s in servo_map.ids)
    _assert_goals_safe(r)


def test_that_a_normal_end_holds_the_final_command_not_the_sagging_present(servo_map: ServoMap) -> None:
    r = _ready(servo_map)
    r.mock.faults.block(4)  # a loaded joint that lags its command (less than the tracking limit)
    rep = _run(r, _trajectory(servo_map, amplitude=0.2))
    assert rep.completed, rep.faults
    writes = _goal_writes(r)
    present = r.mock.servo(4).get("present_position")
    assert writes[-1] == writes[-2]  # the final command again, for every servo
    assert abs(writes[-1][4] - present) > 100  # not goal = present, which would give up the lag


def test_that_a_rate_below_the_floor_is_refused() -> None:
    with pytest.raises(SafetyError, match="outside 20..2000 Hz"):
        ExecutorConfig(rate_hz=10.0)


def test_that_a_rate_that_would_starve_the_armed_watchdog_is_refused_before_streaming(servo_map: ServoMap) -> None:
    r = make_rig(servo_map)
    preflight(r.group)
    engage(r.group, watchdog_s=0.06)  # 3 units of 20 ms, read back from the servos by the executor
    n0 = len(_goal_writes(r))
    with pytest.raises(SafetyError, match="feeds the 60 ms Bus Watchdog less than twice per timeout"):
        Executor(r.group, r.limits(), ExecutorConfig(rate_hz=25.0)).run(*_trajectory(servo_map))
    assert len(_goal_writes(r)) == n0  # nothing streamed


def test_that_a_tripped_watchdog_is_refused_before_streaming(servo_map: ServoMap) -> None:
    r = _ready(servo_map)
    r.clock.sleep(0.15)  # nobody fed it
    r.mock.advance()
    with pytest.raises(SafetyError, match="has tripped"):
        _run(r)


def test_that_a_failed_step_of_the_stop_does_not_skip_the_rest(servo_map: ServoMap,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    import drivers.executor as executor_module
    from drivers.errors import CommunicationError

    def refuse(group, timeout_s):
        raise CommunicationError("write timeout")

    monkeypatch.setattr(executor_module, "arm_watchdog", refuse)  # the stop's first step fails
    r = _ready(servo_map)

    def fail(bus) -> None:
        raise RuntimeError("a bug")

    r.mock.faults.at(r.clock.now() + 0.3, fail)
    rep = _run(r, stop_policy=StopPolicy.LIMP, limp_s=0.3)
    assert [f.kind for f in rep.faults] == [FaultKind.HOST, FaultKind.COMMUNICATION]
    assert "re-arming the Bus Watchdog failed" in rep.faults[1].message
    assert not any(r.mock.servo(s).torque_on for s in servo_map.ids)  # the ramp and torque off still ran
    assert _pwm_accepted(r) == [0] * len(servo_map)


def test_that_a_limp_stop_also_reaches_a_quarantined_servo(servo_map: ServoMap) -> None:
    r = _ready(servo_map)
    r.mock.faults.at(r.clock.now() + 0.3, lambda bus: bus.faults.silence(2))
    rep = _run(r, stop_policy=StopPolicy.LIMP, limp_s=0.3)
    assert not rep.completed and 2 in r.group.quarantined
    # servo 2 stopped answering, not listening: it got the ramp and the torque off too
    assert not r.mock.servo(2).torque_on


def _too_fast(servo_map: ServoMap):
    """Every joint swung at up to ~6 rad/s on irregular rows, one row 1 mrad past a limit."""
    t = np.concatenate([np.linspace(0.0, 0.3, 4), np.linspace(0.32, 1.0, 9), [1.003, 1.4]])
    mid = 0.5 * (servo_map.lower_rad + servo_map.upper_rad)
    swing = np.minimum(0.6, 0.4 * (servo_map.upper_rad - servo_map.lower_rad))
    q = mid + np.sin(2 * np.pi * t / 0.6)[:, None] * swing[None, :]
    q[-2, 0] = servo_map.upper_rad[0] + 0.001
    return servo_map.joint_names, t, q


def _conformed(servo_map: ServoMap, names, t, q, *, rate_hz: float = RATE):
    from robot_rise.filter.command_limits import CommandLimits, conform
    from robot_rise.posture import Posture
    from robot_rise.trajectory import Trajectory

    limits = CommandLimits(servo_map.joint_names, servo_map.lower_rad, servo_map.upper_rad, MAX_V, rate_hz)
    start = Posture("op3", np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]), dict(zip(names, q[0])))
    out = conform(Trajectory("op3", tuple(names), t, q, start), limits)
    return names, out.t, out.q


@pytest.mark.parametrize(("rate", "speed"), [(RATE, 1.0), (50.0, 1.0), (RATE, 0.7)])
def test_that_a_too_fast_trajectory_conformed_by_the_core_streams_without_a_clamp(
        servo_map: ServoMap, rate: float, speed: float) -> None:
    names, t, q = _too_fast(servo_map)
    raw = Executor(_ready(servo_map, initial_rad=q[0]).group, SafetyLimits(servo_map.lower_rad, servo_map.upper_rad,
                   max_velocity_rad_s=MAX_V), ExecutorConfig(rate_hz=rate, speed=speed)).run(names, t, q)
    assert raw.completed and raw.clamped_cycles > 10
    names, tc, qc = _conformed(servo_map, names, t, q, rate_hz=rate)
    r = _ready(servo_map, initial_rad=qc[0])
    rep = Executor(r.group, r.limits(max_velocity_rad_s=MAX_V), ExecutorConfig(rate_hz=rate, speed=speed)).run(names, tc, qc)
    assert rep.completed and rep.clamped_cycles == 0
    assert tc[-1] > t[-1]  # slowed, not clipped
    _assert_goals_safe(r, rate)


def _expected(servo_map: ServoMap, traj, tolerance_rad: float):
    from drivers.safety import ExpectedPositions

    _, t, q = traj
    return ExpectedPositions(t, q, np.full(len(servo_map), tolerance_rad))


def test_that_tracking_is_watched_against_the_expected_positions_instead_of_the_command(servo_map: ServoMap) -> None:
    traj = _trajectory(servo_map, amplitude=1.0)
    # the first-order servo lags its 1 rad/s command by ~0.04 rad: beyond an absolute 0.02 rad ...
    r = _ready(servo_map)
    rep = Executor(r.group, r.limits(max_velocity_rad_s=MAX_V, max_tracking_error_rad=0.02),
                   ExecutorConfig(rate_hz=RATE)).run(*traj)
    assert {f.kind for f in rep.faults} == {FaultKind.TRACKING} and rep.max_expected_ratio is None
    # ... and within 0.08 rad of where it is expected to be: the run completes
    r = _ready(servo_map)
    rep = Executor(r.group, r.limits(max_velocity_rad_s=MAX_V, max_tracking_error_rad=0.02),
                   ExecutorConfig(rate_hz=RATE, expected=_expected(servo_map, traj, 0.08))).run(*traj)
    assert rep.completed, rep.faults
    assert rep.max_tracking_error_rad > 0.02 and rep.max_expected_ratio is not None and rep.max_expected_ratio < 1
    assert rep.max_expected_error_rad is not None and rep.max_expected_error_rad < 0.08


def _first_cycle_beyond(log_path, servo_map: ServoMap, expected, joint: int, dt: float) -> int:
    """The first logged cycle whose present position of ``joint`` is beyond its tolerance (the
    executor's rule: the tolerance plus the joint's distance at the first cycle)."""
    rows = [line.split(",") for line in log_path.read_text().splitlines()[1:]]
    n = len(servo_map)
    pos = np.array([float(row[2 + n + joint]) for row in rows])
    want = np.array([interpolate(expected.t_s, expected.q_rad, int(row[0]) * dt)[joint] for row in rows])
    tolerance = expected.tolerance_rad[joint] + abs(pos[0] - want[0])
    return int(rows[int(np.argmax(np.abs(pos - want) > tolerance))][0])


def test_that_a_joint_blocked_mid_motion_stops_the_run_within_100_ms_of_leaving_its_tolerance(
        servo_map: ServoMap, tmp_path) -> None:
    traj = _trajectory(servo_map, amplitude=1.0)
    expected = _expected(servo_map, traj, 0.08)
    r = _ready(servo_map)
    r.mock.faults.at(r.clock.now() + 0.4, lambda bus: bus.faults.block(9))
    log = tmp_path / "run.csv"
    rep = _run(r, traj, expected=expected, log_path=log)
    j = servo_map.ids.index(9)
    assert not rep.completed and [(f.kind, f.index) for f in rep.faults] == [(FaultKind.TRACKING, j)]
    fault_cycle = rep.stats.cycles - 1
    beyond = _first_cycle_beyond(log, servo_map, expected, j, 1 / RATE)
    assert 0.4 * RATE < beyond <= fault_cycle <= beyond + 0.1 * RATE
    _assert_goals_safe(r)


@pytest.fixture(scope="module")
def proven_get_up(tmp_path_factory: pytest.TempPathFactory):
    """``make demo``'s get-up (prone, seed 0) as the filter is to write it: conformed to the
    executor's limits, proven, with its command limits and predicted positions in the report."""
    from robot_rise.proof import prove
    from robot_rise.filter.command_limits import (
        COMMAND_LIMITS_KEY,
        command_limits_for,
        conform,
    )
    from robot_rise.proof.prediction import (
        PREDICTED_KEY,
        PredictedPositions,
        predicted_positions,
    )
    from robot_rise.model import load_robot
    from robot_rise.rise import RiseOptions, rise
    from robot_rise.sampling import sample_lying
    from robot_rise.seal import sealed
    from robot_rise.trajectory import write_trajectory

    robot = load_robot()
    result = rise(robot, sample_lying(robot, "prone", 1, 0).postures[0], RiseOptions(seed=0))
    assert result.proven, result.reason
    limits = command_limits_for(robot)
    traj = conform(result.trajectory, limits)
    rec, _, proof = prove(robot, traj, scene="flat")
    assert proof.proven, proof.problems
    predicted = predicted_positions(rec)  # no ensemble: the floor alone, the strictest watch
    traj = sealed(traj.with_report(**proof.to_dict(), **{COMMAND_LIMITS_KEY: limits.to_dict(), PREDICTED_KEY: predicted}))  # what was just proven
    path = tmp_path_factory.mktemp("get_up") / "rise.json"
    write_trajectory(path, traj)
    return robot, path, traj, PredictedPositions.from_dict(predicted)


def test_that_a_proven_get_up_runs_on_the_twin_unclamped_and_within_its_prediction(
        proven_get_up, capsys: pytest.CaptureFixture[str]) -> None:
    from robot_rise.cli import main

    _, path, _, _ = proven_get_up
    assert main(["execute", str(path), "--mock", "--twin", "--yes"]) == 0
    out = capsys.readouterr().out
    assert "tracking watched against the band from the proof's predicted positions to the goals" in out
    assert "safety-clamped cycles 0" in out and "FAULT" not in out and "completed" in out
    ratio = float(re.search(r"\(([\d.]+) of its tolerance\)", out).group(1))  # type: ignore[union-attr]
    assert ratio < 1.0
    assert re.search(r"twin: .*: upright", out)


def test_that_a_joint_blocked_mid_get_up_on_the_twin_stops_it_within_100_ms_of_leaving_its_tolerance(
        proven_get_up, tmp_path) -> None:
    from drivers.clock import FakeClock
    from drivers.mockbus import attached
    from drivers.safety import ExpectedPositions
    from drivers.servo_map import load_servo_map
    from drivers.session import connect, mock_url_for
    from robot_rise.sim.twin import MujocoTwin

    robot, _, traj, predicted = proven_get_up
    smap = load_servo_map(robot.directory / "servos.toml")
    idx = smap.index_of(traj.joint_names)
    q = np.asarray(traj.q)[:, idx]
    # block the joint that moves most in the middle third of the motion, at its fastest there
    speed = np.abs(np.diff(q, axis=0)) / np.diff(traj.t)[:, None]
    middle = (traj.t[1:] > traj.duration_s / 3) & (traj.t[1:] < 2 * traj.duration_s / 3)
    row, joint = np.unravel_index(int(np.argmax(np.where(middle[:, None], speed, 0.0))), speed.shape)
    block_at = float(traj.t[row])
    pidx = smap.index_of(predicted.joint_names)
    expected = ExpectedPositions(predicted.t_s, predicted.q_rad[:, pidx], predicted.tolerance_rad[pidx])
    twin = MujocoTwin(robot, "flat", start=traj.start)
    clock = FakeClock()
    url = mock_url_for(smap, initial_rad=traj.start.joints, clock=clock, plant=twin)
    log = tmp_path / "run.csv"
    with connect(smap, url) as conn:
        preflight(conn.group)
        engage(conn.group, watchdog_s=0.1)
        emulator = attached(url.removeprefix("dxlsim://"))
        assert emulator is not None
        emulator.faults.at(clock.now() + block_at, lambda bus: bus.faults.block(smap.servos[joint].id))
        limits = SafetyLimits(smap.lower_rad, smap.upper_rad)
        rep = Executor(conn.group, limits, ExecutorConfig(expected=expected, log_path=log)).run(
            traj.joint_names, traj.t, traj.q)
    assert not rep.completed and [(f.kind, f.index) for f in rep.faults] == [(FaultKind.TRACKING, joint)]
    beyond = _first_cycle_beyond(log, smap, expected, joint, 1 / RATE)
    assert block_at * RATE <= beyond <= rep.stats.cycles - 1 <= beyond + 0.1 * RATE
    assert rep.commands is not None and rep.clamped_cycles == 0
    assert np.all(rep.commands >= smap.lower_rad) and np.all(rep.commands <= smap.upper_rad)


_SHIPPED = sorted(p for p in (Path(__file__).parent.parent / "configs" / "motions" / "op3").glob("*.json")
                  if p.name != "index.json" and not p.name.endswith(".start.json"))


# the two that went furthest past the old band around the prediction alone (1.17 and 1.14 of it)
_WORST_BEFORE = ("prone_elbow_pushup.json", "supine_situp_rock_robust.json")


@pytest.mark.parametrize("twin, names", [
    (True, None),
    (False, _WORST_BEFORE),
    pytest.param(False, None, marks=pytest.mark.slow),  # the plain mock streams on the wall clock: 54 s for all
], ids=["twin-all", "mock-worst-two", "mock-all"])
def test_that_every_shipped_motion_completes_on_the_mock_bus_with_no_fault_and_no_clamp(twin, names, capsys) -> None:
    """Issue 41: the first thing a user runs. The plain mock's servos follow their goals more closely
    than the proof's loaded lag: inside the band from the prediction to the goals, not a fault."""
    from robot_rise.cli import main

    assert len(_SHIPPED) >= 12
    worst = 0.0
    for path in [p for p in _SHIPPED if names is None or p.name in names]:
        code = main(["execute", str(path), "--mock", "--yes", *(["--twin"] if twin else [])])
        out = capsys.readouterr().out
        assert code == 0 and "FAULT" not in out and "safety-clamped cycles 0" in out, f"{path.name}:\n{out}"
        worst = max(worst, float(re.search(r"\(([\d.]+) of its tolerance\)", out).group(1)))  # type: ignore[union-attr]
    assert worst < 0.7  # measured 0.38 (mock) and 0.48 (twin): room before the band is reached


def test_that_bench_mock_execute_runs_a_file_on_the_mock_and_the_twin_and_counts_it_clean(capsys) -> None:
    from robot_rise.cli import main

    quick = next(p for p in _SHIPPED if p.name == "prone_elbow_knees_quick.json")
    assert main(["bench", "mock-execute", str(quick), "--rises", "0"]) == 0
    out = capsys.readouterr().out
    assert "2 of 2 runs clean (no fault, no clamped cycle) over 1 files" in out
    assert re.search(r"prone_elbow_knees_quick.json\s+mock clean; clamped cycles 0; band used 0\.\d+", out)
