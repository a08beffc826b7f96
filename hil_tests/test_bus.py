"""DynamixelBus and ServoGroup against the emulator: scan, group I/O, error bytes, isolation."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.control_table import HardwareErrorBits
from drivers.errors import ServoStatusError, ServoTimeout
from drivers.startup import preflight
from hil_tests.conftest import Rig


def test_that_scan_finds_every_servo_and_its_model(rig: Rig) -> None:
    found = rig.bus.scan(range(1, 23))
    assert sorted(found) == list(range(1, 21)) and {r.model_number for r in found.values()} == {1020}


def test_that_a_silent_servo_raises_a_timeout_naming_it(rig: Rig) -> None:
    rig.mock.faults.silence(4)
    with pytest.raises(ServoTimeout) as e:
        rig.bus.read(4, 132, 4)
    assert e.value.ids == (4,)


def test_that_a_refused_write_raises_with_the_error_byte(rig: Rig) -> None:
    rig.bus.write(1, 64, b"\x01")
    with pytest.raises(ServoStatusError, match="access error") as e:
        rig.bus.write(1, 11, b"\x04")
    assert "torque off" in e.value.hint


def test_that_group_feedback_is_read_in_radians_with_one_fast_read(rig: Rig) -> None:
    report = preflight(rig.group)
    assert report.fast_read
    before = rig.bus.stats.packets_sent
    fb = rig.group.read_feedback()
    assert rig.bus.stats.packets_sent - before == 1
    assert fb.valid.all() and np.allclose(fb.position_rad, 0.0) and np.allclose(fb.voltage_v, 12.0)


def test_that_the_alert_bit_of_one_servo_is_surfaced_not_dropped(rig: Rig) -> None:
    preflight(rig.group)
    rig.mock.faults.hardware_error(7, HardwareErrorBits.OVERHEATING)
    rig.clock.sleep(0.01)
    fb = rig.group.read_feedback()
    k = rig.group.ids.index(7)
    assert fb.error_byte[k] & 0x80 and fb.hardware_error[k] == HardwareErrorBits.OVERHEATING
    assert fb.alert[k] and fb.valid.sum() == 20


def test_that_one_silent_servo_costs_only_its_own_data_and_is_quarantined(rig: Rig) -> None:
    preflight(rig.group)
    rig.mock.faults.silence(12)
    k = rig.group.ids.index(12)
    fb = rig.group.read_feedback()
    assert not fb.valid[k] and fb.valid.sum() == 19
    rig.group.read_feedback()
    assert 12 in rig.group.quarantined
    before = rig.clock.now()
    fb = rig.group.read_feedback()  # quarantined: fast read of the 19 others, no timeout wait
    assert fb.valid.sum() == 19 and rig.clock.now() - before < 0.001


def test_that_a_quarantined_servo_is_readmitted_when_it_answers_a_reping(rig: Rig) -> None:
    preflight(rig.group)
    rig.mock.faults.silence(3)
    for _ in range(3):
        rig.group.read_feedback()
    rig.mock.faults.restore(3)
    for _ in range(rig.group.reping_every):
        fb = rig.group.read_feedback()
        if rig.group.readmitted:
            break
    assert 3 not in rig.group.quarantined and fb.valid.all()


def test_that_corrupted_replies_are_counted_and_never_taken_as_data(rig: Rig) -> None:
    preflight(rig.group)
    rig.mock.faults.corrupt_probability = 0.3
    for _ in range(30):
        fb = rig.group.read_feedback()
        assert np.all(np.abs(fb.position_rad[fb.valid]) < 1e-6)
    assert rig.bus.stats.corrupt_replies + rig.bus.stats.fast_read_failures > 0


class _CountingPort:
    """Wraps the emulator port and counts input flushes."""

    def __init__(self, inner) -> None:
        self.inner = inner
        self.flushes = 0

    @property
    def timeout(self):
        return self.inner.timeout

    @timeout.setter
    def timeout(self, value) -> None:
        self.inner.timeout = value

    def write(self, data: bytes):
        return self.inner.write(data)

    def read(self, size: int = 1) -> bytes:
        return self.inner.read(size)

    def reset_input_buffer(self) -> None:
        self.flushes += 1
        self.inner.reset_input_buffer()


def test_that_clean_cycles_skip_the_input_flush_and_a_bad_reply_brings_it_back(rig: Rig) -> None:
    preflight(rig.group)
    port = _CountingPort(rig.bus.port)
    rig.bus.port = port
    q = np.zeros(20)
    for _ in range(5):
        rig.group.write_goals(q, defer=True)
        assert rig.group.read_feedback().valid.all()
    assert port.flushes == 0
    rig.mock.faults.truncate_probability = 1.0
    rig.group.write_goals(q, defer=True)
    assert not rig.group.read_feedback().valid.all()
    rig.mock.faults.truncate_probability = 0.0
    flushes = port.flushes
    rig.group.write_goals(q, defer=True)
    rig.group.read_feedback()
    assert port.flushes == flushes + 1  # the next transaction starts from an empty input


def test_that_a_stale_byte_left_in_the_input_never_becomes_data(rig: Rig) -> None:
    preflight(rig.group)
    q = np.zeros(20)
    rig.group.write_goals(q, defer=True)
    rig.group.read_feedback()
    rig.bus.port._pending.insert(0, (0.0, b"\xff"))  # a stray byte after a clean cycle
    fb = rig.group.read_feedback()  # fast read misaligned: rejected, plain read recovers
    assert np.all(np.abs(fb.position_rad[fb.valid]) < 1e-6) and fb.valid.all()
    assert rig.bus.stats.fast_read_failures == 1


def test_that_pipelined_cycles_keep_the_wire_order_and_read_what_sequential_cycles_read(rig: Rig) -> None:
    from drivers.pipeline import pipelined_cycles
    from drivers.protocol import Instruction

    from drivers.startup import engage

    preflight(rig.group)
    engage(rig.group, watchdog_s=None)
    assert rig.group.pipelinable
    start = len(rig.mock.log)
    q = np.clip(np.full(20, 0.2), rig.servo_map.lower_rad, rig.servo_map.upper_rad)
    assert pipelined_cycles(rig.group, q, 12) == 12
    kinds = [p.instruction for p in rig.mock.log[start:]]
    assert kinds == [Instruction.SYNC_WRITE, Instruction.FAST_SYNC_READ] * 12
    assert rig.bus.stats.fast_read_failures == 0
    rig.clock.sleep(0.5)
    fb = rig.group.read_feedback()
    assert np.allclose(fb.position_rad, q, atol=0.002)


def test_that_pipelined_cycles_fall_back_and_isolate_a_silent_servo(rig: Rig) -> None:
    from drivers.pipeline import pipelined_cycles

    preflight(rig.group)
    rig.mock.faults.silence(8)
    assert pipelined_cycles(rig.group, np.zeros(20), 6) == 0
    assert 8 in rig.group.quarantined and not rig.group.pipelinable


def test_that_a_pipelined_reply_out_of_order_is_drained_before_the_fallback_read(rig: Rig, monkeypatch) -> None:
    from drivers.pipeline import pipelined_cycles
    from drivers.protocol import Instruction

    preflight(rig.group)
    decode = rig.group.decode_fast_feedback
    calls = iter([None] + [0] * 100)

    def flaky(raw):  # the first reply decodes as out of order (e.g. an ID mix-up)
        return decode(raw) if next(calls) is not None or raw is None else None

    monkeypatch.setattr(rig.group, "decode_fast_feedback", lambda raw: flaky(raw))
    start = len(rig.mock.log)
    assert pipelined_cycles(rig.group, np.zeros(20), 4) == 4
    kinds = [p.instruction for p in rig.mock.log[start:] if p.instruction != Instruction.SYNC_WRITE]
    # 4 cycles + the request already on the wire when reply 1 was rejected (drained) + the
    # fallback read of cycle 1; each reply is taken before the next request leaves
    assert kinds == [Instruction.FAST_SYNC_READ] * 6
    assert rig.bus.stats.stale_replies == 0 and rig.bus.stats.fast_read_failures == 0
    assert rig.bus.port.in_waiting == 0  # no reply left over: each was matched to its own request


def test_that_an_empty_id_list_writes_to_no_servo(rig: Rig) -> None:
    for s in rig.servo_map.servos:
        rig.bus.write(s.id, 64, b"\x01")
    start = len(rig.mock.log)
    rig.group.torque(False, ids=[])
    rig.group.write_all(65, 1, 1, ids=())
    assert len(rig.mock.log) == start  # nothing sent at all
    assert all(rig.mock.servo(s.id).torque_on for s in rig.servo_map.servos)
    rig.group.torque(False, ids=[3])
    assert [s.id for s in rig.servo_map.servos if not rig.mock.servo(s.id).torque_on] == [3]
    rig.group.torque(False)  # None (the default) still means every servo
    assert not any(rig.mock.servo(s.id).torque_on for s in rig.servo_map.servos)


def test_that_feedback_without_the_indirect_block_matches_the_indirect_read(rig: Rig) -> None:
    import struct

    from drivers.protocol import Instruction

    preflight(rig.group)
    rig.mock.plant.set_position(5, 0.4)
    rig.mock.faults.hardware_error(9, HardwareErrorBits.OVERHEATING)
    rig.clock.sleep(0.01)
    rig.mock.advance()
    packed = rig.group.read_feedback()
    rig.group.use_indirect = False
    start = len(rig.mock.log)
    plain = rig.group.read_feedback()
    reads = [(p.instruction, struct.unpack_from("<HH", p.params)) for p in rig.mock.log[start:]]
    assert reads == [(Instruction.FAST_SYNC_READ, (126, 22)), (Instruction.SYNC_READ, (70, 1))]
    for name in ("position_rad", "velocity_rad_s", "effort_raw", "hardware_error", "temperature_c", "voltage_v"):
        assert np.array_equal(getattr(plain, name), getattr(packed, name)), name
    assert plain.valid.all() and plain.hardware_error[rig.group.ids.index(9)] == HardwareErrorBits.OVERHEATING


def test_that_a_servo_group_refuses_a_model_without_the_shared_register_layout(rig: Rig, monkeypatch) -> None:
    from types import MappingProxyType

    import drivers.servo_map as sm
    from drivers.control_table import ControlTable, control_table
    from drivers.errors import ControlTableError
    from drivers.group import ServoGroup

    xm = control_table("XM430-W350")
    odd = ControlTable("ODD-1", 9999, MappingProxyType({n: r for n, r in xm.registers.items() if n != "goal_pwm"}),
                       xm.defaults, xm.current_unit_a, xm.operating_modes)
    monkeypatch.setattr(sm.ServoSpec, "table", property(lambda self: odd))
    with pytest.raises(ControlTableError, match="ODD-1 has no 2-byte register at 100 \\(goal_pwm\\)"):
        ServoGroup(rig.bus, rig.servo_map)
