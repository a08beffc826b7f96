"""The fault campaign of the 2.0 driver on a Protocol 1.0 bus (issue 43): the fault injector on
the 1.0 emulator, byte for byte, then every fault kind of ``robot-rise bench bus1-faults`` with 0
goals out of limits, the fault stopped or reported, 0 tracebacks and the servos left safe."""

from __future__ import annotations

import json

import pytest

import drivers.mockbus as mb
from drivers.clock import FakeClock
from drivers.errors import ProtocolError
from drivers.protocol1 import ErrorBits1, Instruction1, decode_status1, encode_instruction1, read_params1, write_params1
from drivers.session import mock_bus_for
from robot_rise.bench.bus1_faults import Bus1Fault, GoalSpy1, fault_bench_map, run_bus1_fault

_PRESENT_POSITION = read_params1(36, 2)


def _bus(**faults: object) -> mb.MockBus1:
    bus = mb.MockBus1({1: "MX-28", 2: "MX-28", 3: "MX-28", 4: "AX-18A"}, clock=FakeClock(1.0),
                      faults=mb.FaultInjector(**faults))  # type: ignore[arg-type]
    assert isinstance(bus, mb.MockBus1)
    return bus


def _read(bus: mb.MockBus1, sid: int, params: bytes = _PRESENT_POSITION) -> list[bytes]:
    return [r.data for r in bus.receive(encode_instruction1(sid, Instruction1.READ, params))]


def _status_error(bus: mb.MockBus1, sid: int) -> int:
    (reply,) = _read(bus, sid)
    return decode_status1(reply).params[0]


# ---- the fault injector on the 1.0 emulator -----------------------------------------------------
def test_that_dropped_statuses_are_seeded_and_counted_on_a_1_0_bus() -> None:
    runs = []
    for _ in range(2):
        bus = _bus(drop_probability=0.3, seed=7)
        answered = [bool(_read(bus, 1 + k % 4)) for k in range(60)]
        assert bus.faults.dropped == answered.count(False) > 0
        runs.append(answered)
    assert runs[0] == runs[1]  # the same seed drops the same statuses
    assert [bool(_read(b, 1 + k % 4)) for b in [_bus(drop_probability=0.3, seed=8)] for k in range(60)] != runs[0]


def test_that_a_corrupted_1_0_status_fails_its_checksum() -> None:
    bus = _bus(corrupt_probability=1.0, seed=1)
    for sid in (1, 4):
        (reply,) = _read(bus, sid)
        with pytest.raises(ProtocolError):
            decode_status1(reply)
    assert bus.faults.corrupted == 2


def test_that_a_lost_bulk_read_status_silences_the_servos_listed_after_it() -> None:
    bus = _bus()
    params = bytes((0x00, 2, 1, 36, 2, 2, 36, 2, 3, 36))  # MX 1, 2, 3: present position
    bulk = encode_instruction1(0xFE, Instruction1.BULK_READ, params)
    assert [decode_status1(r.data).servo_id for r in bus.receive(bulk)] == [1, 2, 3]
    bus.faults.silence(2)
    assert [decode_status1(r.data).servo_id for r in bus.receive(bulk)] == [1]
    bus.faults.restore(2)
    bus.faults.drop_probability = 1.0
    assert bus.receive(bulk) == [] and bus.faults.dropped == 1  # the first lost: nobody else speaks


def test_that_a_missing_1_0_servo_stays_silent_but_still_hears_writes() -> None:
    bus = _bus()
    bus.faults.silence(4)
    assert _read(bus, 4) == []
    assert bus.receive(encode_instruction1(4, Instruction1.PING)) == []
    assert bus.receive(encode_instruction1(4, Instruction1.WRITE, write_params1(30, (600).to_bytes(2, "little")))) == []
    assert bus.servo(4).get("goal_position") == 600


def test_that_an_overload_alarm_sets_the_status_bit_and_the_alarm_shutdown_frees_the_shaft() -> None:
    bus = _bus()
    assert _status_error(bus, 2) == 0
    bus.faults.hardware_error(2, ErrorBits1.OVERLOAD)
    bus.clock.advance(0.01)  # type: ignore[attr-defined]
    assert _status_error(bus, 2) & ErrorBits1.OVERLOAD
    assert bus.servo(2).get("torque_limit") == 0 and bus.servo(2).shutdowns == 1  # factory Alarm Shutdown: overload
    assert _status_error(bus, 1) == 0


def test_that_the_supply_voltage_reaches_each_1_0_servo_and_its_own_limit_raises_the_alarm() -> None:
    bus = _bus()
    bus.faults.input_voltage_v = 15.5  # inside the MX-28's 16 V, above the AX-18A's 14 V
    bus.clock.advance(0.01)  # type: ignore[attr-defined]
    assert _read(bus, 1, read_params1(42, 1))[0][5] == 155  # Present Voltage [0.1 V]
    assert _status_error(bus, 1) & ErrorBits1.INPUT_VOLTAGE == 0
    assert _status_error(bus, 4) & ErrorBits1.INPUT_VOLTAGE
    bus.faults.voltage_by_id[4] = 12.0
    bus.clock.advance(0.01)  # type: ignore[attr-defined]
    assert _status_error(bus, 4) & ErrorBits1.INPUT_VOLTAGE == 0  # a live alarm: while the condition lasts


def test_that_the_goal_spy_sees_a_goal_outside_the_limits_even_when_the_servo_refuses_it() -> None:
    smap = fault_bench_map()
    bus = mock_bus_for(smap, clock=FakeClock(), wire_timing=False)
    spy = GoalSpy1(bus, smap)
    spec = smap.by_id(17)
    lo, hi = spec.limit_ticks
    bus.receive(encode_instruction1(17, Instruction1.WRITE, write_params1(30, (hi + 5).to_bytes(2, "little"))))
    sync = bytes((30, 2)) + b"".join(bytes((sid,)) + lo.to_bytes(2, "little") for sid in (17, 18))
    bus.receive(encode_instruction1(0xFE, Instruction1.SYNC_WRITE, sync))
    assert spy.goals == 3 and spy.goal_packets == 2 and spy.out_of_limits == [(17, hi + 5)]


# ---- the campaign: every fault kind -------------------------------------------------------------
_EXPECTED = {
    Bus1Fault.MISSING_MX: "communication",
    Bus1Fault.MISSING_AX: "communication",
    Bus1Fault.OVERLOAD: "hardware error",
    Bus1Fault.OVERHEATING: "temperature",
    Bus1Fault.UNDERVOLTAGE: "input voltage",
    Bus1Fault.OVERVOLTAGE: "input voltage",
    Bus1Fault.HOST_TERMINATED: "interrupted",
    Bus1Fault.HOST_KILLED: "SIGKILL",
}


@pytest.mark.parametrize("kind", list(Bus1Fault), ids=[k.value for k in Bus1Fault])
def test_that_each_fault_on_the_1_0_bus_is_stopped_or_reported_with_every_goal_in_limits(kind: Bus1Fault) -> None:
    row = run_bus1_fault(kind, seed=0)
    assert row.goals_written > 20 * 50, row.how  # the stream ran (at least half a second of goals) before the fault
    assert row.goals_out_of_limits == 0
    assert row.stopped or row.reported, row.how
    assert not row.traceback_seen, row.how
    assert row.safe_end, row.end_state
    assert row.ok
    if kind in _EXPECTED:
        assert row.stopped and _EXPECTED[kind] in row.how, row.how
    if kind is Bus1Fault.OVERLOAD:
        assert "recovered [" in row.how and "holding in limits" in row.end_state, (row.how, row.end_state)
    if kind is Bus1Fault.HOST_KILLED:  # nothing stops the servos: they hold the last goal, in limits
        assert row.end_state == "20 holding in limits", row.how


def test_that_an_in_process_fault_row_is_reproducible_from_its_seed() -> None:
    a, b = (run_bus1_fault(Bus1Fault.CORRUPT, seed=3) for _ in range(2))
    assert (a.goals_written, a.how, a.end_state) == (b.goals_written, b.how, b.end_state)


def test_that_bench_bus1_faults_prints_its_rows_as_json(capsys: pytest.CaptureFixture[str]) -> None:
    from robot_rise.cli import main

    assert main(["bench", "bus1-faults", "--kind", "overload", "--kind", "missing-ax", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert [r["fault"] for r in out["rows"]] == ["overload", "missing-ax"]
    assert out["ok"] == out["total"] == 2 and out["goals_out_of_limits"] == 0 and out["tracebacks"] == 0
