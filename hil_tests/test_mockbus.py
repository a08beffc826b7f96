"""The emulator speaks real Protocol 2.0 and keeps the firmware's rules."""

from __future__ import annotations

import random
import struct

import pytest
import serial
from dynamixel_sdk import (
    COMM_SUCCESS,
    GroupSyncRead,
    GroupSyncWrite,
    PacketHandler,
    PortHandler,
)

import drivers.mockbus as mb
from drivers.clock import FakeClock
from drivers.control_table import HardwareErrorBits
from drivers.protocol import (
    ALERT_BIT,
    BROADCAST_ID,
    Instruction,
    StatusError,
    bulk_read_params,
    decode_packet,
    encode_packet,
    read_params,
    sync_write_params,
    write_params,
)


def _bus(**kw: object) -> mb.MockBus:
    return mb.MockBus.from_ids([1, 2, 3], clock=FakeClock(), **kw)


def _ask(bus: mb.MockBus, servo_id: int, inst: int, params: bytes = b""):
    replies = bus.receive(encode_packet(servo_id, inst, params))
    return [decode_packet(r.data) for r in replies]


def test_that_ping_returns_model_number_and_firmware() -> None:
    (p,) = _ask(_bus(), 2, Instruction.PING)
    assert struct.unpack("<HB", p.data) == (1020, 46) and p.error == 0


def test_that_broadcast_ping_is_answered_by_every_servo_in_id_order() -> None:
    assert [p.servo_id for p in _ask(_bus(), BROADCAST_ID, Instruction.PING)] == [1, 2, 3]


def test_that_eeprom_is_write_protected_while_torque_is_on() -> None:
    bus = _bus()
    _ask(bus, 1, Instruction.WRITE, write_params(64, b"\x01"))
    (p,) = _ask(bus, 1, Instruction.WRITE, write_params(11, b"\x04"))
    assert p.error & 0x7F == StatusError.ACCESS
    assert bus.servo(1).get("operating_mode") == 3
    _ask(bus, 1, Instruction.WRITE, write_params(64, b"\x00"))
    (p,) = _ask(bus, 1, Instruction.WRITE, write_params(11, b"\x04"))
    assert p.error == 0 and bus.servo(1).get("operating_mode") == 4


def test_that_read_only_registers_refuse_writes() -> None:
    (p,) = _ask(_bus(), 1, Instruction.WRITE, write_params(132, b"\x00\x00\x00\x00"))
    assert p.error & 0x7F == StatusError.ACCESS


def test_that_goal_outside_position_limits_is_refused_with_data_limit_error() -> None:
    bus = _bus()
    _ask(bus, 1, Instruction.WRITE, write_params(48, struct.pack("<i", 3000)))
    (p,) = _ask(bus, 1, Instruction.WRITE, write_params(116, struct.pack("<i", 3500)))
    assert p.error & 0x7F == StatusError.DATA_LIMIT
    assert bus.servo(1).get("goal_position") == 2048


def test_that_indirect_data_reads_the_mapped_registers() -> None:
    bus = _bus()
    addrs = b"".join(struct.pack("<H", a) for a in (132, 133, 134, 135, 7))
    _ask(bus, 2, Instruction.WRITE, write_params(168, addrs))
    (p,) = _ask(bus, 2, Instruction.READ, read_params(224, 5))
    assert struct.unpack("<iB", p.data) == (2048, 2)


def test_that_hardware_error_sets_the_alert_bit_and_shutdown_drops_torque() -> None:
    bus = _bus()
    _ask(bus, 3, Instruction.WRITE, write_params(64, b"\x01"))
    bus.faults.hardware_error(3, HardwareErrorBits.OVERLOAD)
    bus.clock.sleep(0.01)  # type: ignore[attr-defined]
    (p,) = _ask(bus, 3, Instruction.READ, read_params(70, 1))
    assert p.error & ALERT_BIT and p.data == bytes([HardwareErrorBits.OVERLOAD])
    assert not bus.servo(3).torque_on
    (p,) = _ask(bus, 3, Instruction.WRITE, write_params(64, b"\x01"))
    assert p.error & 0x7F == StatusError.RESULT_FAIL


def test_that_reboot_clears_the_error_and_keeps_eeprom() -> None:
    bus = _bus(boot_time_s=0.05)
    _ask(bus, 1, Instruction.WRITE, write_params(9, b"\x07"))
    bus.faults.hardware_error(1, HardwareErrorBits.OVERLOAD)
    bus.clock.sleep(0.01)  # type: ignore[attr-defined]
    _ask(bus, 1, Instruction.REBOOT)
    assert _ask(bus, 1, Instruction.PING) == []  # still booting
    bus.clock.sleep(0.06)  # type: ignore[attr-defined]
    (p,) = _ask(bus, 1, Instruction.READ, read_params(9, 1))
    assert p.error == 0 and p.data == b"\x07" and bus.servo(1).hardware_error == 0


def test_that_bus_watchdog_trips_without_traffic_and_blocks_goal_writes_until_cleared() -> None:
    bus = _bus()
    _ask(bus, 1, Instruction.WRITE, write_params(64, b"\x01"))
    _ask(bus, 1, Instruction.WRITE, write_params(98, b"\x05"))  # 100 ms
    bus.clock.sleep(0.09)  # type: ignore[attr-defined]
    (p,) = _ask(bus, 1, Instruction.READ, read_params(98, 1))  # feeds it
    assert p.data == b"\x05"
    bus.clock.sleep(0.15)  # type: ignore[attr-defined]
    (p,) = _ask(bus, 1, Instruction.READ, read_params(98, 1))
    assert struct.unpack("<b", p.data)[0] == -1
    (p,) = _ask(bus, 1, Instruction.WRITE, write_params(116, struct.pack("<i", 2100)))
    assert p.error & 0x7F == StatusError.DATA_RANGE
    _ask(bus, 1, Instruction.WRITE, write_params(98, b"\x00"))
    (p,) = _ask(bus, 1, Instruction.WRITE, write_params(116, struct.pack("<i", 2100)))
    assert p.error == 0


def test_that_reg_write_waits_for_action() -> None:
    bus = _bus()
    _ask(bus, 2, Instruction.REG_WRITE, write_params(65, b"\x01"))
    assert bus.servo(2).get("led") == 0
    assert _ask(bus, BROADCAST_ID, Instruction.ACTION) == []
    assert bus.servo(2).get("led") == 1


def test_that_sync_write_changes_only_the_listed_servos_and_sends_no_reply() -> None:
    bus = _bus()
    out = _ask(bus, BROADCAST_ID, Instruction.SYNC_WRITE, sync_write_params(65, 1, {1: b"\x01", 3: b"\x01"}))
    assert out == [] and [bus.servo(i).get("led") for i in (1, 2, 3)] == [1, 0, 1]


def test_that_bulk_read_answers_each_item_with_its_own_span() -> None:
    out = _ask(_bus(), BROADCAST_ID, Instruction.BULK_READ, bulk_read_params([(1, 0, 2), (3, 7, 1)]))
    assert [(p.servo_id, p.data) for p in out] == [(1, struct.pack("<H", 1020)), (3, b"\x03")]


def test_that_a_silent_servo_breaks_the_fast_sync_read_frame() -> None:
    from drivers.protocol import sync_read_params

    bus = _bus()
    bus.faults.silence(2)
    replies = bus.receive(encode_packet(BROADCAST_ID, Instruction.FAST_SYNC_READ, sync_read_params(132, 4, [1, 2, 3])))
    (r,) = replies
    length = r.data[5] | (r.data[6] << 8)
    assert len(r.data) < 7 + length  # announced more than was sent


def test_that_the_emulator_never_crashes_or_answers_random_or_corrupt_bytes() -> None:
    bus = _bus()
    rng = random.Random(5)
    good = encode_packet(1, Instruction.PING)
    for _ in range(300):
        noise = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 40)))
        corrupt = bytearray(good)
        corrupt[rng.randrange(4, len(good))] ^= 1 << rng.randrange(8)
        assert bus.receive(noise + bytes(corrupt) + b"\x00" * 12) == []
    assert bus.packets_received == 0
    assert len(bus.receive(good)) == 1  # and it still answers a good packet afterwards


def test_that_replies_take_their_wire_time_with_wire_timing_on() -> None:
    bus = mb.MockBus.from_ids([1], clock=FakeClock(), wire_timing=True, baud_rate=1_000_000,
                              return_delay_units=250)
    (r,) = bus.receive(encode_packet(1, Instruction.PING))
    assert r.ready_s == pytest.approx((10 + 14) * 10e-6 + 500e-6)


def test_that_url_handler_ignores_a_port_at_the_wrong_baud_rate() -> None:
    mb.attach("wrongbaud", mb.MockBus.from_ids([1], clock=FakeClock(), baud_rate=1_000_000))
    port = serial.serial_for_url("dxlsim://wrongbaud", baudrate=57600, timeout=0.01)
    port.write(encode_packet(1, Instruction.PING))
    assert port.read(14) == b""


class _UrlPortHandler(PortHandler):
    """dynamixel-sdk's PortHandler, opening pyserial URLs (the only override)."""

    def setupPort(self, cflag_baud):  # noqa: N802 (SDK naming)
        self.ser = serial.serial_for_url(self.port_name, baudrate=self.baudrate, timeout=0)
        self.is_open = True
        self.tx_time_per_byte = (1000.0 / self.baudrate) * 10.0
        return True


def test_that_dynamixel_sdk_group_classes_work_against_the_emulator() -> None:
    mb.attach("sdk", mb.MockBus.from_ids([1, 2, 3], baud_rate=1_000_000))
    port = _UrlPortHandler("dxlsim://sdk")
    assert port.openPort()
    ph = PacketHandler(2.0)
    model, result, error = ph.ping(port, 2)
    assert (model, result, error) == (1020, COMM_SUCCESS, 0)
    writer = GroupSyncWrite(port, ph, 116, 4)
    for i in (1, 2, 3):
        writer.addParam(i, list(struct.pack("<i", 2000 + i)))
    assert writer.txPacket() == COMM_SUCCESS
    reader = GroupSyncRead(port, ph, 116, 4)
    for i in (1, 2, 3):
        reader.addParam(i)
    assert reader.txRxPacket() == COMM_SUCCESS
    assert [reader.getData(i, 116, 4) for i in (1, 2, 3)] == [2001, 2002, 2003]
    assert reader.fastSyncRead() == COMM_SUCCESS
    assert [reader.getData(i, 116, 4) for i in (1, 2, 3)] == [2001, 2002, 2003]


def test_that_bulk_write_applies_each_item_to_its_own_servo_and_span() -> None:
    from drivers.protocol import bulk_write_params

    bus = _bus()
    out = _ask(bus, BROADCAST_ID, Instruction.BULK_WRITE,
               bulk_write_params([(1, 65, b"\x01"), (3, 116, struct.pack("<i", 2100))]))
    assert out == []
    assert bus.servo(1).get("led") == 1 and bus.servo(3).get("goal_position") == 2100
    assert bus.servo(2).get("led") == 0 and bus.servo(1).get("goal_position") == 2048


def test_that_temperature_rises_under_load_and_not_without_torque() -> None:
    loaded, idle = _bus(), _bus()
    for bus in (loaded, idle):
        _ask(bus, 1, Instruction.WRITE, write_params(116, struct.pack("<i", 2400)))
    _ask(loaded, 1, Instruction.WRITE, write_params(64, b"\x01"))
    loaded.faults.block(1)  # pushing against an obstacle toward a goal 0.5 rad away: stall torque
    loaded.faults.heating_gain = idle.faults.heating_gain = 50.0
    for bus in (loaded, idle):
        bus.clock.sleep(20.0)  # type: ignore[attr-defined]
        bus.advance()
    assert loaded.servo(1).get("present_temperature") > 40
    assert idle.servo(1).get("present_temperature") == 30
    assert loaded.servo(2).get("present_temperature") == 30
