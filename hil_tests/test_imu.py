"""The OP3's IMU on the bus: the OpenCR sub-controller (ID 200, model 0x7400) on the emulator.

Registers, units and mounting: drivers/imu.py (two public sources named beside the table).
"""

from __future__ import annotations

import math
import statistics
import struct

import numpy as np
import pytest

from drivers.imu import (
    IMU_BLOCK_ADDRESS,
    IMU_BLOCK_SIZE,
    OPENCR_ID,
    OPENCR_MODEL_NUMBER,
    STANDARD_GRAVITY_M_S2,
    Imu,
    ImuSample,
    ImuStatus,
    OpenCrImu,
    decode_imu_block,
    encode_imu_block,
    read_cycle,
)
from drivers.mockbus.emulated_imu import EmulatedImu
from drivers.mockbus.plant import ImuNoise, ImuState
from drivers.protocol import (
    BROADCAST_ID,
    Instruction,
    StatusError,
    decode_packet,
    encode_packet,
    write_params,
)
from drivers.servo_map import ServoMap
from drivers.startup import preflight
from hil_tests.conftest import Rig, make_rig

DEG = math.pi / 180.0


def _rig(servo_map: ServoMap, **imu_kw: object) -> tuple[Rig, OpenCrImu]:
    rig = make_rig(servo_map, imu=EmulatedImu(**imu_kw))  # type: ignore[arg-type]
    return rig, OpenCrImu(rig.bus)


def _imu_requests(rig: Rig) -> int:
    return sum(1 for p in rig.mock.log if p.instruction == Instruction.BULK_READ and p.params[0] == OPENCR_ID)


def test_that_a_ping_of_id_200_finds_the_opencr_model_0x7400(servo_map: ServoMap) -> None:
    rig, imu = _rig(servo_map)
    found = rig.bus.ping(OPENCR_ID)
    assert found is not None and found.model_number == OPENCR_MODEL_NUMBER == 0x7400
    probe = imu.probe()
    assert probe.ok and "OpenCR" in probe.message
    # the servos are still found where they were, and the OpenCR answers a broadcast ping last
    replies = rig.mock.receive(encode_packet(BROADCAST_ID, Instruction.PING))
    assert [decode_packet(r.data).servo_id for r in replies] == [*sorted(servo_map.ids), OPENCR_ID]


def test_that_without_an_imu_the_probe_says_so_and_the_read_is_a_status(servo_map: ServoMap) -> None:
    rig = make_rig(servo_map)
    imu = OpenCrImu(rig.bus)
    assert not imu.probe().found
    sample = imu.read()
    assert sample.status is ImuStatus.NO_REPLY and not sample.valid
    assert sample.consecutive_failures == 1 and all(math.isnan(v) for v in sample.angular_velocity_rad_s)


def test_that_known_register_values_decode_to_si_in_the_torso_frame(servo_map: ServoMap) -> None:
    rig, imu = _rig(servo_map)
    # sensor frame: gyro x +10 deg/s (164 counts), y -20 deg/s; acc y +0.5 g, z +1 g;
    # roll 10.0 deg, pitch 5.0 deg, yaw 180.0 deg (the board sits turned half a turn in the torso)
    rig.mock.imu.fixed_block = struct.pack("<9h", 164, -328, 0, 0, 8192, 16384, 100, 50, 1800)  # type: ignore[union-attr]
    s = imu.read()
    assert s.valid and isinstance(imu, Imu)
    np.testing.assert_allclose(s.angular_velocity_rad_s, (-10 * DEG, 20 * DEG, 0.0), atol=1e-9)
    np.testing.assert_allclose(s.specific_force_m_s2, (0.0, -0.5 * STANDARD_GRAVITY_M_S2, STANDARD_GRAVITY_M_S2),
                               atol=1e-9)
    # the torso is the sensor turned back by 180 deg about z: roll and pitch change sign, yaw is 0
    np.testing.assert_allclose(s.roll_pitch_yaw_rad, (-10 * DEG, -5 * DEG, 0.0), atol=1e-9)
    assert s.t_s == rig.clock.now()


def test_that_the_registers_hold_what_the_firmware_writes_for_an_upright_robot_at_rest(servo_map: ServoMap) -> None:
    rig, _ = _rig(servo_map)
    _, data = rig.bus.read(OPENCR_ID, IMU_BLOCK_ADDRESS, IMU_BLOCK_SIZE)
    assert struct.unpack("<9h", data) == (0, 0, 0, 0, 0, 16384, 0, 0, 1800)


def test_that_a_state_round_trips_through_the_registers_within_their_resolution(servo_map: ServoMap) -> None:
    rig, imu = _rig(servo_map)
    half = 0.35
    state = ImuState(quat_wxyz=(math.cos(half), math.sin(half) * 0.6, 0.0, math.sin(half) * 0.8),
                     angular_velocity_rad_s=(0.3, -1.2, 2.5), specific_force_m_s2=(1.5, -3.0, 8.0))
    rig.mock.imu.state = state  # type: ignore[union-attr]
    s = imu.read()
    np.testing.assert_allclose(s.angular_velocity_rad_s, state.angular_velocity_rad_s, atol=0.5 / 16.4 * DEG)
    np.testing.assert_allclose(s.specific_force_m_s2, state.specific_force_m_s2, atol=STANDARD_GRAVITY_M_S2 / 16384)
    dot = abs(float(np.dot(s.quat_wxyz, state.quat_wxyz)))
    assert 2 * math.degrees(math.acos(min(1.0, dot))) < 0.2  # 0.1 deg registers
    # the accelerometer saturates at 2 g like the MPU9250 at its full scale, it does not wrap
    _gyro, accel, _ = decode_imu_block(encode_imu_block((0, 0, 0), (0, 0, 50.0), (1, 0, 0, 0)))
    assert accel[2] == pytest.approx(2 * STANDARD_GRAVITY_M_S2, rel=1e-3)


def test_that_noise_and_bias_are_settable_and_seeded(servo_map: ServoMap) -> None:
    rig, imu = _rig(servo_map)
    emulated = rig.mock.imu
    assert emulated is not None
    noise = ImuNoise(gyro_noise_rad_s=0.02, accel_noise_m_s2=0.1, gyro_bias_rad_s=(0.05, 0.0, -0.03),
                     accel_bias_m_s2=(0.0, 0.2, 0.0), seed=7)
    emulated.noise = noise
    first = [imu.read() for _ in range(400)]
    gx = [s.angular_velocity_rad_s[0] for s in first]
    ay = [s.specific_force_m_s2[1] for s in first]
    assert statistics.fmean(gx) == pytest.approx(0.05, abs=0.005)
    assert statistics.fmean(ay) == pytest.approx(0.2, abs=0.02)
    assert statistics.stdev(gx) == pytest.approx(0.02, rel=0.15)
    assert statistics.stdev(ay) == pytest.approx(0.1, rel=0.15)
    emulated.noise = noise  # the same seed again: the same readings
    again = [imu.read() for _ in range(20)]
    assert [s.angular_velocity_rad_s for s in again] == [s.angular_velocity_rad_s for s in first[:20]]
    emulated.noise = ImuNoise(gyro_noise_rad_s=0.02, seed=8)
    assert [imu.read().angular_velocity_rad_s for _ in range(5)] != [s.angular_velocity_rad_s for s in first[:5]]
    with pytest.raises(ValueError, match="gyro_noise_rad_s"):
        ImuNoise(gyro_noise_rad_s=-1.0)


def test_that_read_only_registers_refuse_writes_and_the_leds_take_them(servo_map: ServoMap) -> None:
    rig, _ = _rig(servo_map)
    replies = rig.mock.receive(encode_packet(OPENCR_ID, Instruction.WRITE, write_params(32, b"\x01\x00")))
    assert decode_packet(replies[0].data).error & 0x7F == StatusError.ACCESS
    rig.bus.write(OPENCR_ID, 26, struct.pack("<H", 0x7C00))  # LED_RGB
    assert rig.mock.imu.get("led_rgb") == 0x7C00  # type: ignore[union-attr]


def test_that_a_failed_imu_read_is_a_status_and_the_servo_loop_goes_on(servo_map: ServoMap) -> None:
    rig, imu = _rig(servo_map)
    preflight(rig.group)
    q = np.zeros(len(servo_map))
    statuses, failures = [], []
    for k in range(60):
        if k == 10:
            rig.mock.faults.silence(OPENCR_ID)
        if k == 40:
            rig.mock.faults.restore(OPENCR_ID)
        rig.group.write_goals(q, defer=True)
        feedback, sample = read_cycle(rig.group, imu)
        assert feedback.valid.all()  # every servo read, every cycle
        statuses.append(sample.status)
        failures.append(sample.consecutive_failures)
        rig.clock.advance(0.01)
    assert statuses[:10] == [ImuStatus.OK] * 10
    assert statuses[10:15] == [ImuStatus.NO_REPLY] * 5 and failures[10:15] == [1, 2, 3, 4, 5]
    # lost after 5 failures: asked only every 10th cycle, the others cost no bus time
    assert set(statuses[15:40]) == {ImuStatus.LOST, ImuStatus.NO_REPLY}
    assert statuses[15:40].count(ImuStatus.NO_REPLY) <= 3
    assert imu.failures <= 8 and imu.reads < 40
    # back once it answers again (at its next retry)
    assert statuses[-1] is ImuStatus.OK and failures[-1] == 0 and not imu.lost
    assert rig.mock.faults.silent_ids == set()


def test_that_a_lost_imu_does_not_cost_a_timeout_every_cycle(servo_map: ServoMap) -> None:
    rig, imu = _rig(servo_map)
    rig.mock.faults.silence(OPENCR_ID)
    for _ in range(imu.lost_after):
        imu.read()
    before = _imu_requests(rig)
    for _ in range(20):
        imu.read()
    assert _imu_requests(rig) - before == 2  # 20 cycles, one retry every 10


def test_that_one_bulk_read_can_carry_the_servos_feedback_and_the_imu(servo_map: ServoMap) -> None:
    """The same bus cycle in one instruction: the OpenCR answers its item of a BULK_READ after the servos."""
    rig, _ = _rig(servo_map)
    items = [(sid, 132, 4) for sid in servo_map.ids] + [(OPENCR_ID, IMU_BLOCK_ADDRESS, IMU_BLOCK_SIZE)]
    r = rig.bus.bulk_read(items)
    assert r.complete and len(r.data[OPENCR_ID]) == IMU_BLOCK_SIZE
    _gyro, accel, _ = decode_imu_block(r.data[OPENCR_ID])
    assert accel == pytest.approx((0.0, 0.0, STANDARD_GRAVITY_M_S2))
    # the OP3 node firmware has no Fast Bulk Read: the OpenCR's item breaks that frame (read it plainly)
    assert not rig.bus.bulk_read(items, fast=True).complete


def test_that_the_tilt_of_a_sample_is_its_z_axis_from_the_vertical() -> None:
    def tilt(q: tuple[float, float, float, float]) -> float:
        return ImuSample(0.0, quat_wxyz=q).tilt_rad

    assert tilt((1.0, 0.0, 0.0, 0.0)) == pytest.approx(0.0)
    half = np.radians(30.0) / 2
    assert tilt((np.cos(half), np.sin(half), 0.0, 0.0)) == pytest.approx(np.radians(30.0))  # roll
    assert tilt((np.cos(half), 0.0, 0.0, np.sin(half))) == pytest.approx(0.0)  # yaw is no tilt
    assert tilt((0.0, 0.0, 1.0, 0.0)) == pytest.approx(np.pi)  # upside down
    assert np.isnan(ImuSample(0.0, status=ImuStatus.NO_REPLY).tilt_rad)
