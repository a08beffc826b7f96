"""The IMU: a small interface any board can implement, and the OP3's OpenCR sub-controller on the bus.

:class:`Imu` is the contract: ``read()`` returns an :class:`ImuSample` in SI units in the torso
frame (angular velocity [rad/s], specific force [m/s^2], orientation as a quaternion), stamped on
the bus clock. A failed read is a status in the sample (:class:`ImuStatus`, values NaN), never an
exception: the servo loop goes on without the IMU, and the caller sees how many reads in a row
failed (``consecutive_failures``).

:class:`OpenCrImu` reads the ROBOTIS OP3's IMU through its OpenCR sub-controller, a Dynamixel
Protocol 2.0 device on the servo bus (ID 200, model number 0x7400). One cycle: the servo group's
feedback read, then one BULK_READ of the IMU block (gyro, accelerometer, fused roll/pitch/yaw,
18 bytes at address 32) on the same bus, before the next cycle's goal write
(:func:`read_cycle`). The group's own reads are (fast) sync reads the OpenCR does not take part
in, so the IMU cannot share their frame; a BULK_READ item is used instead of READ because group
reads never retry (a silent IMU costs one reply timeout, not two). After ``lost_after`` failures
in a row the IMU is asked only every ``retry_every`` cycles (as :class:`drivers.group.ServoGroup`
quarantines a silent servo), so a dead IMU does not cost a timeout every cycle.

The register table (:data:`OPENCR_REGISTERS`) and the units are checked against two public
sources, named beside the table.
"""

from __future__ import annotations

import enum
import logging
import math
import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

from drivers.bus import DynamixelBus, PingResult
from drivers.control_table import Register
from drivers.errors import CommunicationError
from drivers.protocol import BITS_PER_BYTE, instruction_length, status_length

if TYPE_CHECKING:
    from drivers.group import Feedback, ServoGroup

__all__ = [
    "OPENCR_ID",
    "OPENCR_MODEL_NUMBER",
    "OPENCR_REGISTERS",
    "OPENCR_MEMORY_SIZE",
    "IMU_BLOCK_ADDRESS",
    "IMU_BLOCK_SIZE",
    "GYRO_LSB_PER_DEG_S",
    "ACCEL_LSB_PER_G",
    "ORIENTATION_UNIT_DEG",
    "STANDARD_GRAVITY_M_S2",
    "OP3_MOUNT",
    "ImuStatus",
    "ImuSample",
    "ImuProbe",
    "Imu",
    "OpenCrImu",
    "encode_imu_block",
    "decode_imu_block",
    "read_cycle",
]

_log = logging.getLogger(__name__)

# ---- the OpenCR as the OP3 sub-controller: control table ------------------------------------
# Sources (checked against each other):
#  [fw]  OpenCR firmware, OP3 node: ROBOTIS-GIT/OpenCR,
#        arduino/opencr_arduino/opencr/libraries/OP3/examples/opencr_op3/dxl_node_op3.h
#        (DXL_NODE_OP3_ID 200, DXL_NODE_OP3_MODLE_NUMBER 0x7400; struct dxl_mem_op3_t gives every
#        field's address and C type) and dxl_hw_op3.cpp (what the loop writes there: Gyro_X..Z =
#        IMU.SEN.gyroADC[0..2], Acc_X..Z = IMU.SEN.accRAW[0..2], Roll/Pitch/Yaw =
#        (int16)((IMU.rpy[i] - offset) * 10), i.e. 0.1 deg); the sensor ranges are set in
#        libraries/IMU/MPU9250.cpp (gyro 2000 deg/s full scale, accelerometer 2 g).
#  [fw2] ROBOTIS-OP3 open_cr_module (ROBOTIS-GIT/ROBOTIS-OP3, open_cr_module/include/.../
#        open_cr_module.h and src/open_cr_module.cpp), the host side ROBOTIS ships: bulk-reads
#        gyro_x/y/z and acc_x/y/z as int16, GYRO_FACTOR = 2000/32800 deg/s per count,
#        ACCEL_FACTOR = 2/32768 g per count, G_ACC = 9.80665; it turns both vectors into the robot
#        frame as (-x, -y, +z) of the sensor's ("align axis of Accelerometer to robot").
#  Also read: ROBOTIS-Framework robotis_device/devices/sensor/OPEN-CR.device (stored copy in
#        Robotics-Sensors/bellande_humanoid_robot_intelligence_control_system_framework): the same
#        addresses and 2-byte sizes (gyro_x 32 .. acc_z 42 signed; roll 44, pitch 46, yaw 48,
#        listed unsigned 0..4096 there, but [fw] writes signed int16 tenths of a degree), and the
#        e-manual's sub-controller page (support.robotis.com/en/product/robotis-op3/
#        sub_controller(opencr).htm; its control table read through the idminer.gitbook.io
#        mirror, section 2.7.3 "RAM area"): the same addresses and sizes, but it names 32..37
#        Gyro_Z, Gyro_Y, Gyro_X (the CM-730's order). The firmware ([fw]) writes gyro x at 32 and
#        ROBOTIS's own host code ([fw2]) and device file read it there: we follow the firmware.
_R = Register
_ROWS = (
    _R("model_number", 0, 2, False),
    _R("firmware_version", 2, 1, False),
    _R("id", 3, 1),
    _R("baud_rate", 4, 1),
    _R("return_delay_time", 5, 1),  # 2 us units, as the servos
    _R("status_return_level", 16, 1),
    _R("roll_offset", 18, 2, signed=True),  # written by the firmware after an IMU_Control calibration
    _R("pitch_offset", 20, 2, signed=True),
    _R("yaw_offset", 22, 2, signed=True),
    _R("dynamixel_power", 24, 1),
    _R("led", 25, 1),
    _R("led_rgb", 26, 2),
    _R("buzzer", 28, 2),
    _R("button", 30, 1, False),
    _R("voltage", 31, 1, False),  # 0.1 V
    _R("gyro_x", 32, 2, False, signed=True),  # sensor frame, GYRO_LSB_PER_DEG_S counts per deg/s
    _R("gyro_y", 34, 2, False, signed=True),
    _R("gyro_z", 36, 2, False, signed=True),
    _R("acc_x", 38, 2, False, signed=True),  # sensor frame, ACCEL_LSB_PER_G counts per g
    _R("acc_y", 40, 2, False, signed=True),
    _R("acc_z", 42, 2, False, signed=True),
    _R("roll", 44, 2, False, signed=True),  # fused orientation of the sensor frame, 0.1 deg
    _R("pitch", 46, 2, False, signed=True),
    _R("yaw", 48, 2, False, signed=True),
    _R("imu_control", 50, 1),  # bits 0..2: start roll/pitch/yaw offset calibration
)
OPENCR_REGISTERS: Mapping[str, Register] = MappingProxyType({r.name: r for r in _ROWS})
OPENCR_MEMORY_SIZE = 51  # bytes: up to IMU_Control (50) [fw]
OPENCR_ID = 200  # [fw] DXL_NODE_OP3_ID
OPENCR_MODEL_NUMBER = 0x7400  # [fw] DXL_NODE_OP3_MODLE_NUMBER
IMU_BLOCK_ADDRESS = OPENCR_REGISTERS["gyro_x"].address  # 32: gyro, accelerometer, roll/pitch/yaw
IMU_BLOCK_SIZE = OPENCR_REGISTERS["yaw"].address + OPENCR_REGISTERS["yaw"].size - IMU_BLOCK_ADDRESS  # 18 bytes
_BLOCK = struct.Struct("<9h")
GYRO_LSB_PER_DEG_S = 16.4  # [counts per deg/s] MPU9250 at 2000 deg/s full scale ([fw] MPU9250.cpp; [fw2] 32800/2000)
ACCEL_LSB_PER_G = 16384.0  # [counts per g] MPU9250 at 2 g full scale ([fw] MPU9250.cpp; [fw2] 32768/2)
ORIENTATION_UNIT_DEG = 0.1  # [deg per count] roll/pitch/yaw ([fw] dxl_hw_op3_get_rpy: degrees x 10)
STANDARD_GRAVITY_M_S2 = 9.80665  # [m/s^2] one g ([fw2] G_ACC)
# Rotation from the sensor (OpenCR board) frame to the torso frame, R_torso_sensor, row-major: the
# board lies in the OP3's torso turned half a turn about the vertical, so torso = (-x, -y, +z) of
# the sensor's ([fw2] negates gyro and accelerometer x and y "to align axis ... to robot"). The
# torso frame is the robot model's (configs/robots/op3/robot.xml): x forward, y left, z up.
OP3_MOUNT: tuple[tuple[float, float, float], ...] = ((-1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, 1.0))
_INT16 = (-32768, 32767)


# ---- conversions (pure) ----------------------------------------------------------------------


def _mount_matrix(mount: Sequence[Sequence[float]]) -> np.ndarray:
    m = np.asarray(mount, dtype=float)
    if m.shape != (3, 3) or not np.allclose(m @ m.T, np.eye(3), atol=1e-9) or not np.isclose(np.linalg.det(m), 1.0):
        raise ValueError(f"mount must be a 3x3 rotation matrix (R_torso_sensor), got {mount!r}")
    return m


def _quat_to_matrix(q: Sequence[float]) -> np.ndarray:
    w, x, y, z = (float(v) for v in q)
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _matrix_to_quat(m: np.ndarray) -> tuple[float, float, float, float]:
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = (0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s)
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = ((m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s)
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = ((m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s)
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = ((m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s)
    sign = -1.0 if q[0] < 0 else 1.0  # w >= 0
    return tuple(float(sign * v) for v in q)  # type: ignore[return-value]


def _rpy_to_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll) (Z-Y-X Euler angles, radians)."""
    cr, sr, cp, sp, cy, sy = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch), math.cos(yaw), math.sin(yaw)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def _matrix_to_rpy(m: np.ndarray) -> tuple[float, float, float]:
    pitch = math.asin(max(-1.0, min(1.0, -float(m[2, 0]))))
    return math.atan2(float(m[2, 1]), float(m[2, 2])), pitch, math.atan2(float(m[1, 0]), float(m[0, 0]))


def _to_int16(value: float) -> int:
    """Round and saturate like the sensor (a reading past full scale stays at full scale)."""
    if not math.isfinite(value):
        raise ValueError(f"cannot encode {value} in a register")
    return int(max(_INT16[0], min(_INT16[1], round(value))))


def encode_imu_block(angular_velocity_rad_s: Sequence[float], specific_force_m_s2: Sequence[float],
                     quat_wxyz: Sequence[float], *,
                     mount: Sequence[Sequence[float]] = OP3_MOUNT) -> bytes:
    """The 18 bytes the OpenCR holds at :data:`IMU_BLOCK_ADDRESS` for a torso state.

    Args:
        angular_velocity_rad_s: torso angular velocity in the torso frame [rad/s], 3 values.
        specific_force_m_s2: ``R^T (a - g)`` in the torso frame [m/s^2], 3 values.
        quat_wxyz: torso orientation in the world (w, x, y, z).
        mount: R_torso_sensor (the board's mounting), row-major 3x3.

    Returns:
        gyro x, y, z, acc x, y, z, roll, pitch, yaw as little-endian int16 in the sensor frame,
        in the units of the table (saturated at full scale).
    """
    m = _mount_matrix(mount)
    w_s = m.T @ np.asarray(angular_velocity_rad_s, dtype=float)
    f_s = m.T @ np.asarray(specific_force_m_s2, dtype=float)
    rpy = _matrix_to_rpy(_quat_to_matrix(quat_wxyz) @ m)  # R_world_sensor = R_world_torso R_torso_sensor
    values = [*(math.degrees(v) * GYRO_LSB_PER_DEG_S for v in w_s),
              *(v / STANDARD_GRAVITY_M_S2 * ACCEL_LSB_PER_G for v in f_s),
              *(math.degrees(a) / ORIENTATION_UNIT_DEG for a in rpy)]
    return _BLOCK.pack(*(_to_int16(v) for v in values))


def decode_imu_block(data: bytes, *, mount: Sequence[Sequence[float]] = OP3_MOUNT
                     ) -> tuple[tuple[float, float, float], tuple[float, float, float], tuple[float, float, float, float]]:
    """SI values in the torso frame from the 18 bytes at :data:`IMU_BLOCK_ADDRESS`.

    Returns:
        (angular velocity [rad/s], specific force [m/s^2], orientation quaternion w, x, y, z of
        the torso in the world; its yaw is the board's, which drifts).

    Raises:
        ValueError: ``data`` is not :data:`IMU_BLOCK_SIZE` bytes.
    """
    if len(data) != IMU_BLOCK_SIZE:
        raise ValueError(f"IMU block is {IMU_BLOCK_SIZE} bytes, got {len(data)}")
    m = _mount_matrix(mount)
    raw = _BLOCK.unpack(bytes(data))
    w_s = np.radians(np.asarray(raw[0:3], dtype=float) / GYRO_LSB_PER_DEG_S)
    f_s = np.asarray(raw[3:6], dtype=float) / ACCEL_LSB_PER_G * STANDARD_GRAVITY_M_S2
    roll, pitch, yaw = (math.radians(v * ORIENTATION_UNIT_DEG) for v in raw[6:9])
    quat = _matrix_to_quat(_rpy_to_matrix(roll, pitch, yaw) @ m.T)  # R_world_torso = R_world_sensor R_sensor_torso
    w_t, f_t = m @ w_s, m @ f_s
    return ((float(w_t[0]), float(w_t[1]), float(w_t[2])), (float(f_t[0]), float(f_t[1]), float(f_t[2])), quat)


# ---- the interface -----------------------------------------------------------------------------


class ImuStatus(enum.Enum):
    """How one IMU read went."""

    OK = "ok"
    NO_REPLY = "no reply"  # no valid status packet in time (silent, or a corrupt reply)
    REFUSED = "refused"  # the device answered with an error number
    LOST = "lost"  # not asked this cycle: too many failures in a row (asked again every few cycles)
    PORT_ERROR = "port error"  # the port itself failed (the servo read will report it too)


_NAN3 = (math.nan, math.nan, math.nan)


@dataclass(frozen=True)
class ImuSample:
    """One IMU reading in SI units, torso frame (x forward, y left, z up for the OP3).

    Attributes:
        t_s: bus clock time of the read [s].
        angular_velocity_rad_s: torso angular velocity, torso frame [rad/s], 3 values (NaN when
            the read failed).
        specific_force_m_s2: accelerometer reading ``R^T (a - g)``, torso frame [m/s^2], 3 values
            (+9.81 along up at rest; NaN when the read failed).
        quat_wxyz: torso orientation in the world from the board's own fusion (w, x, y, z; yaw is
            the board's, which drifts; NaN when the read failed).
        status: how the read went (:class:`ImuStatus`).
        consecutive_failures: failed reads in a row, this one included (0 when OK).
        error: the status error byte the device answered with (0 if none).
    """

    t_s: float
    angular_velocity_rad_s: tuple[float, float, float] = _NAN3
    specific_force_m_s2: tuple[float, float, float] = _NAN3
    quat_wxyz: tuple[float, float, float, float] = (math.nan, math.nan, math.nan, math.nan)
    status: ImuStatus = ImuStatus.OK
    consecutive_failures: int = 0
    error: int = 0

    @property
    def valid(self) -> bool:
        """The values were read this cycle."""
        return self.status is ImuStatus.OK

    @property
    def roll_pitch_yaw_rad(self) -> tuple[float, float, float]:
        """Z-Y-X Euler angles of :attr:`quat_wxyz` [rad] (NaN when the read failed)."""
        if not self.valid:
            return _NAN3
        return _matrix_to_rpy(_quat_to_matrix(self.quat_wxyz))

    @property
    def tilt_rad(self) -> float:
        """Angle between the torso's z axis and the world vertical [rad] (NaN when the read failed)."""
        if not self.valid:
            return math.nan
        return math.acos(max(-1.0, min(1.0, float(_quat_to_matrix(self.quat_wxyz)[2, 2]))))


@runtime_checkable
class Imu(Protocol):
    """An IMU another board can implement: one call per control cycle, never raising on a failed read."""

    def read(self) -> ImuSample:
        """One reading (or a sample whose ``status`` says why there is none)."""
        ...


@dataclass(frozen=True)
class ImuProbe:
    """What a ping of the IMU's address found.

    Attributes:
        found: something answered at the address.
        model_number: its model number (0 if nothing answered).
        firmware_version: its firmware version (0 if nothing answered).
        message: one line for the operator.
    """

    found: bool
    model_number: int = 0
    firmware_version: int = 0
    message: str = ""

    @property
    def ok(self) -> bool:
        """An OpenCR sub-controller (model 0x7400) answered."""
        return self.found and self.model_number == OPENCR_MODEL_NUMBER


class OpenCrImu:
    """The OP3's IMU, read through the OpenCR sub-controller on the servo bus.

    Args:
        bus: the servo bus (the OpenCR shares it with the servos).
        device_id: the OpenCR's Dynamixel ID (200 on the OP3).
        mount: R_torso_sensor, the board's mounting in the torso, row-major 3x3
            (:data:`OP3_MOUNT` for the OP3).
        lost_after: failed reads in a row after which the IMU counts as lost.
        retry_every: while lost, ask it only every this many cycles (others return ``LOST``
            without bus traffic).
    """

    def __init__(self, bus: DynamixelBus, *, device_id: int = OPENCR_ID,
                 mount: Sequence[Sequence[float]] = OP3_MOUNT, lost_after: int = 5, retry_every: int = 10) -> None:
        if lost_after < 1 or retry_every < 1:
            raise ValueError(f"lost_after ({lost_after}) and retry_every ({retry_every}) must be >= 1")
        self.bus = bus
        self.device_id = device_id
        self.mount = tuple(tuple(float(v) for v in row) for row in _mount_matrix(mount))
        self.lost_after = lost_after
        self.retry_every = retry_every
        self.reads = 0  # read attempts on the bus
        self.failures = 0  # failed read attempts, in total
        self.consecutive_failures = 0
        self._cycle = 0
        self._items = [(device_id, IMU_BLOCK_ADDRESS, IMU_BLOCK_SIZE)]

    @property
    def lost(self) -> bool:
        """``lost_after`` or more reads in a row failed."""
        return self.consecutive_failures >= self.lost_after

    def probe(self) -> ImuProbe:
        """Ping the device and check its model number (never raises on silence)."""
        try:
            found: PingResult | None = self.bus.ping(self.device_id)
        except CommunicationError as e:
            return ImuProbe(False, message=f"IMU at ID {self.device_id}: port error: {e}")
        if found is None:
            return ImuProbe(False, message=f"no IMU answers at ID {self.device_id}")
        probe = ImuProbe(True, found.model_number, found.firmware_version)
        if probe.ok:
            return ImuProbe(True, found.model_number, found.firmware_version,
                            f"OpenCR sub-controller at ID {self.device_id}, firmware {found.firmware_version}")
        return ImuProbe(True, found.model_number, found.firmware_version,
                        f"ID {self.device_id} is model {found.model_number:#06x}, not the OpenCR ({OPENCR_MODEL_NUMBER:#06x})")

    def cycle_wire_time_s(self) -> float:
        """Wire time of one IMU read [s] (request and reply, no byte stuffing, no return delay)."""
        n = instruction_length(5) + status_length(IMU_BLOCK_SIZE)
        return n * BITS_PER_BYTE / self.bus.baud_rate

    def read(self) -> ImuSample:
        """One BULK_READ of the IMU block; a failure is returned as a status, never raised."""
        self._cycle += 1
        now = self.bus.clock.now()
        if self.lost and self._cycle % self.retry_every:
            return ImuSample(now, status=ImuStatus.LOST, consecutive_failures=self.consecutive_failures)
        self.reads += 1
        try:
            r = self.bus.bulk_read(self._items)
        except CommunicationError as e:
            _log.debug("IMU read: port error: %s", e)
            return self._failed(now, ImuStatus.PORT_ERROR)
        data = r.data.get(self.device_id)
        if data is None:
            error = r.errors.get(self.device_id, 0)
            return self._failed(now, ImuStatus.REFUSED if self.device_id in r.errors else ImuStatus.NO_REPLY, error)
        if self.lost:
            _log.warning("IMU at ID %d answers again after %d failed reads", self.device_id, self.consecutive_failures)
        self.consecutive_failures = 0
        gyro, accel, quat = decode_imu_block(data, mount=self.mount)
        return ImuSample(now, gyro, accel, quat, ImuStatus.OK, 0, r.errors.get(self.device_id, 0))

    def _failed(self, now: float, status: ImuStatus, error: int = 0) -> ImuSample:
        self.failures += 1
        self.consecutive_failures += 1
        if self.consecutive_failures == self.lost_after:
            _log.warning("IMU at ID %d lost: %d reads in a row failed (%s); asking every %d cycles",
                         self.device_id, self.consecutive_failures, status.value, self.retry_every)
        return ImuSample(now, status=status, consecutive_failures=self.consecutive_failures, error=error)


def read_cycle(group: ServoGroup, imu: Imu) -> tuple[Feedback, ImuSample]:
    """One cycle's reads on one bus: the servo group's feedback, then the IMU.

    A failed IMU read is in the sample's status; only a failure of the servo read itself (a port
    error) raises, as :meth:`drivers.group.ServoGroup.read_feedback` does.
    """
    feedback = group.read_feedback()
    return feedback, imu.read()
