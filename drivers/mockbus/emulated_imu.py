"""The OP3's OpenCR sub-controller on the emulated bus: a Protocol 2.0 device with an IMU.

A memory image of the OpenCR's control table (:data:`drivers.imu.OPENCR_REGISTERS`) at ID 200,
model number 0x7400. Its IMU registers (gyro, accelerometer, fused roll/pitch/yaw, sensor frame)
are filled at every read from the plant's IMU hook (:class:`drivers.mockbus.plant.ImuSource`:
the physics twin), with the sensor errors of :class:`drivers.mockbus.plant.ImuNoise` added and
the sensor's full scale applied (the accelerometer saturates at 2 g, as the real one). Without a
source it reports :attr:`EmulatedImu.state` (upright and at rest unless a test sets it).

Firmware rules emulated: read-only registers refuse writes (Access Error), reads past the table
are Access Errors, the baud rate register decides whether the device hears the bus.
Not emulated: Fast Sync/Bulk Read (the OP3 node firmware registers ping, read, write, sync and
bulk handlers only), the IMU offset calibration of IMU_Control, buttons, LEDs, the buzzer.
"""

from __future__ import annotations

import logging
import random

from drivers.control_table import RETURN_DELAY_UNIT_S, Register
from drivers.imu import (
    IMU_BLOCK_ADDRESS,
    IMU_BLOCK_SIZE,
    OP3_MOUNT,
    OPENCR_ID,
    OPENCR_MEMORY_SIZE,
    OPENCR_MODEL_NUMBER,
    OPENCR_REGISTERS,
    encode_imu_block,
)
from drivers.mockbus.plant import ImuNoise, ImuSource, ImuState, ImuStateLike
from drivers.protocol import StatusError

__all__ = ["EmulatedImu", "OPENCR_FIRMWARE_VERSION"]

_log = logging.getLogger(__name__)

OPENCR_FIRMWARE_VERSION = 2  # DXL_NODE_OP3_FW_VER of the OP3 node (OpenCR dxl_node_op3.h)
_VOLTAGE_UNITS = 120  # 12.0 V in the 0.1 V unit of the voltage register


class EmulatedImu:
    """The OpenCR sub-controller of an OP3 on the emulated bus.

    Args:
        device_id: Dynamixel ID (200 on the OP3).
        source: where the true inertial state comes from (``None``: :attr:`state`); the
            :class:`~drivers.mockbus.MockBus` wires in its plant's hook when this is ``None``.
        noise: sensor errors added to every reading (seeded; settable later).
        mount: R_torso_sensor, the board's mounting (:data:`drivers.imu.OP3_MOUNT`).
        baud_index: Baud Rate register value (the bus sets it to its own rate).
        return_delay_units: Return Delay Time register value (2 us units).
        firmware_version: reported firmware version.
    """

    def __init__(self, *, device_id: int = OPENCR_ID, source: ImuSource | None = None,
                 noise: ImuNoise | None = None, mount: tuple[tuple[float, ...], ...] = OP3_MOUNT,
                 baud_index: int = 3, return_delay_units: int = 0,
                 firmware_version: int = OPENCR_FIRMWARE_VERSION) -> None:
        self.source = source
        self.mount = mount
        self.state: ImuStateLike = ImuState()
        self.mem = bytearray(OPENCR_MEMORY_SIZE)
        self._set("model_number", OPENCR_MODEL_NUMBER)
        self._set("firmware_version", firmware_version)
        self._set("id", device_id)
        self._set("baud_rate", baud_index)
        self._set("return_delay_time", return_delay_units)
        self._set("status_return_level", 2)
        self._set("voltage", _VOLTAGE_UNITS)
        self._noise = noise or ImuNoise()
        self._rng: random.Random = self._noise.rng()
        self.reads = 0  # IMU block refreshes (tests count them)
        self.last_reported: ImuState | None = None  # what the last read reported (noise included)
        # registers to report as they are (a test's known values, a scripted sensor fault); None:
        # refreshed from the source at every read
        self.fixed_block: bytes | None = None

    # ---- registers -------------------------------------------------------------------------
    def _set(self, name: str, value: int) -> None:
        reg = OPENCR_REGISTERS[name]
        self.mem[reg.address: reg.address + reg.size] = reg.encode(value)

    def set(self, name: str, value: int) -> None:
        """Write register ``name`` directly, without the firmware's checks (the bus's own
        configuration, tests)."""
        self._set(name, value)

    def get(self, name: str) -> int:
        """Integer value of register ``name``."""
        reg = OPENCR_REGISTERS[name]
        return reg.decode(bytes(self.mem[reg.address: reg.address + reg.size]))

    @property
    def id(self) -> int:
        return self.get("id")

    @property
    def return_delay_s(self) -> float:
        """Return Delay Time [s]."""
        return self.get("return_delay_time") * RETURN_DELAY_UNIT_S

    @property
    def noise(self) -> ImuNoise:
        """The sensor errors; setting them restarts the noise generator from their seed."""
        return self._noise

    @noise.setter
    def noise(self, value: ImuNoise) -> None:
        self._noise = value
        self._rng = value.rng()

    # ---- the IMU ---------------------------------------------------------------------------
    def refresh(self) -> None:
        """Write the IMU registers: :attr:`fixed_block` if set, else the source's state with the
        sensor errors added (kept in :attr:`last_reported`)."""
        if self.fixed_block is not None:
            if len(self.fixed_block) != IMU_BLOCK_SIZE:
                raise ValueError(f"fixed_block must be {IMU_BLOCK_SIZE} bytes, got {len(self.fixed_block)}")
            block = bytes(self.fixed_block)
        else:
            true = self.source.imu_state() if self.source is not None else self.state
            reported = self._noise.apply(true, self._rng)
            block = encode_imu_block(reported.angular_velocity_rad_s, reported.specific_force_m_s2,
                                     reported.quat_wxyz, mount=self.mount)
            self.last_reported = reported
        self.mem[IMU_BLOCK_ADDRESS: IMU_BLOCK_ADDRESS + IMU_BLOCK_SIZE] = block
        self.reads += 1

    # ---- instructions ----------------------------------------------------------------------
    def read(self, address: int, length: int) -> tuple[int, bytes]:
        """READ ``length`` bytes at ``address``; returns (status error byte, data)."""
        if length <= 0 or address < 0 or address + length > OPENCR_MEMORY_SIZE:
            return StatusError.ACCESS, b""
        if address < IMU_BLOCK_ADDRESS + IMU_BLOCK_SIZE and address + length > IMU_BLOCK_ADDRESS:
            self.refresh()
        return 0, bytes(self.mem[address: address + length])

    def write(self, address: int, data: bytes) -> int:
        """WRITE ``data`` at ``address``; returns the status error byte (Access Error for
        read-only or unknown bytes, nothing written then)."""
        if not data or address < 0 or address + len(data) > OPENCR_MEMORY_SIZE:
            return StatusError.ACCESS
        touched: dict[str, Register] = {}
        for a in range(address, address + len(data)):
            reg = next((r for r in OPENCR_REGISTERS.values() if r.address <= a < r.address + r.size), None)
            if reg is None or not reg.writable:
                return StatusError.ACCESS
            touched[reg.name] = reg
        self.mem[address: address + len(data)] = data
        if "imu_control" in touched:
            self._set("imu_control", 0)  # calibration not emulated: done at once
        _log.debug("OpenCR %d: wrote %s", self.id, ", ".join(touched))
        return 0

    def ping_data(self) -> bytes:
        """The PING reply data: model number (2 bytes) and firmware version."""
        return bytes(self.mem[0:3])
