"""One emulated X-series servo: a control-table memory image with the firmware's rules.

Rules emulated (ROBOTIS e-manual, X series):
- EEPROM (addresses < 64) is write-protected while Torque Enable is 1 (Access Error).
- Read-only registers reject writes (Access Error); unknown addresses are Access Errors.
- Goal Position outside the Min/Max Position Limit is refused (Data Limit Error) in position mode.
- Indirect Data N reads/writes the byte at Indirect Address N (both blocks 168/224, 578/634).
- Hardware errors set bit 7 (alert) of every status error byte; an error whose bit is set in
  Shutdown clears Torque Enable, and Torque Enable cannot be set again until a reboot.
- Bus Watchdog (98): with torque on and a value 1..127, if no instruction reaches the servo for
  value x 20 ms, the servo stops (goal = present), the register reads -1 and writes to goal
  registers fail with a Data Range Error until 0 is written.
- Reboot: RAM back to defaults, EEPROM kept, hardware errors cleared (unless their cause persists).
"""

from __future__ import annotations

import logging
import struct
from collections.abc import Mapping
from dataclasses import dataclass

from drivers.control_table import (
    CENTER_TICKS,
    EEPROM_END,
    INDIRECT_ADDRESS_1,
    INDIRECT_COUNT,
    INDIRECT_DATA_1,
    MEMORY_SIZE,
    RAD_PER_TICK,
    VELOCITY_UNIT_RAD_S,
    WATCHDOG_UNIT_S,
    ControlTable,
    HardwareErrorBits,
    Register,
)
from drivers.errors import ControlTableError
from drivers.mockbus.plant import ServoCommand, ServoMotion
from drivers.protocol import ALERT_BIT, StatusError
from robot_files.errors import RobotFileError
from robot_files.servo_catalog import product_datasheet

__all__ = ["EmulatedServo", "ThermalModel", "LOAD_MODEL_SUPPLY_V", "motor_figures"]

_log = logging.getLogger(__name__)

_GOAL_REGISTERS = ("goal_pwm", "goal_current", "goal_velocity", "goal_position")
_INDIRECT_BLOCKS = ((INDIRECT_DATA_1, INDIRECT_ADDRESS_1), (634, 578))
_STRUCT_CODE = {1: "B", 2: "H", 4: "I"}  # unsigned struct codes by register size
LOAD_MODEL_SUPPLY_V = 12.0  # [V] the emulated servos' load model: the catalog's figures at 12 V


def motor_figures(model: str) -> tuple[float, float]:
    """(stall torque [N m], no-load speed [rad/s]) of ``model`` at ``LOAD_MODEL_SUPPLY_V``: the
    product's servo catalog's figures (``configs/servos/catalog.toml``), the ones the simulator uses.

    Raises:
        ControlTableError: the catalog is missing or malformed, or lacks the model.
    """
    try:
        sheet = product_datasheet(model)
    except RobotFileError as e:
        raise ControlTableError(str(e), hint=e.hint) from None
    return sheet.stall_torque_at(LOAD_MODEL_SUPPLY_V), sheet.no_load_speed_at(LOAD_MODEL_SUPPLY_V)


@dataclass(frozen=True)
class ThermalModel:
    """First-order motor temperature.

    dT/dt = heating_k_per_nm2 * torque^2 - (T - ambient) / time_constant.

    Attributes:
        ambient_c: [degC].
        heating_k_per_nm2_s: [degC / (N m)^2 / s].
        time_constant_s: cooling time constant [s].
    """

    ambient_c: float = 30.0
    heating_k_per_nm2_s: float = 0.05
    time_constant_s: float = 300.0


class EmulatedServo:
    """State machine of one servo on the emulated bus.

    Args:
        servo_id: initial ID.
        table: the model's control table.
        baud_index: Baud Rate register value to start with.
        return_delay_units: Return Delay Time register value to start with (2 us units).
        initial_position_ticks: shaft position at power-on.
        firmware_version: reported firmware (Fast Sync Read needs >= table minimum).
    """

    def __init__(self, servo_id: int, table: ControlTable, *, baud_index: int = 1,
                 return_delay_units: int = 250, initial_position_ticks: int = CENTER_TICKS,
                 firmware_version: int = 46, thermal: ThermalModel | None = None) -> None:
        self.table = table
        self.stall_torque_nm, self.no_load_speed_rad_s = motor_figures(table.model)
        self.thermal = thermal or ThermalModel()
        self._reg_at_byte: list[Register | None] = [None] * MEMORY_SIZE
        # name -> (reader, writer, address, mask): struct codecs precomputed for speed
        self._fields: dict[str, tuple[struct.Struct, struct.Struct, int, int]] = {}
        for reg in table.registers.values():
            for a in range(reg.address, reg.address + reg.size):
                self._reg_at_byte[a] = reg
            code = _STRUCT_CODE[reg.size]
            self._fields[reg.name] = (struct.Struct("<" + (code.lower() if reg.signed else code)),
                                      struct.Struct("<" + code), reg.address, (1 << (8 * reg.size)) - 1)
        self._indirect_cache: dict[tuple[int, int], tuple[int, ...]] = {}
        self.mem = table.default_memory()
        self._set("id", servo_id)
        self._set("baud_rate", baud_index)
        self._set("return_delay_time", return_delay_units)
        self._set("firmware_version", firmware_version)
        self.position_rad = (initial_position_ticks - CENTER_TICKS) * RAD_PER_TICK
        self._set("present_position", initial_position_ticks)
        self._set("goal_position", initial_position_ticks)
        self.temperature_c = self.thermal.ambient_c
        self.watchdog_last_feed_s = 0.0
        self.watchdog_tripped = False
        self.watchdog_trips = 0  # times the Bus Watchdog tripped since power-on (for tests and tools)
        self.boot_until_s = 0.0
        self.registered: tuple[int, bytes] | None = None
        self.injected_errors = 0
        self.start_s = 0.0

    # ---- raw memory ----------------------------------------------------------------
    def _set(self, name: str, value: int) -> None:
        _, writer, a, mask = self._fields[name]
        writer.pack_into(self.mem, a, int(value) & mask)

    def get(self, name: str) -> int:
        """Integer value of register ``name``."""
        try:
            reader, _, address, _ = self._fields[name]
        except KeyError:
            reg = self.table[name]  # raises, naming the valid registers
            return int.from_bytes(self.mem[reg.address : reg.address + reg.size], "little", signed=reg.signed)
        return reader.unpack_from(self.mem, address)[0]

    @property
    def id(self) -> int:
        return self.mem[7]

    @property
    def torque_on(self) -> bool:
        return self.mem[64] == 1

    @property
    def hardware_error(self) -> int:
        return self.mem[70]

    @property
    def alert(self) -> int:
        return ALERT_BIT if self.mem[70] else 0

    def _resolve(self, address: int) -> int:
        for data_base, addr_base in _INDIRECT_BLOCKS:
            if data_base <= address < data_base + INDIRECT_COUNT:
                k = address - data_base
                a = addr_base + 2 * k
                return self.mem[a] | (self.mem[a + 1] << 8)
        return address

    def _is_indirect(self, address: int, length: int) -> bool:
        return any(address < d + INDIRECT_COUNT and address + length > d for d, _ in _INDIRECT_BLOCKS)

    def _targets(self, address: int, length: int) -> tuple[int, ...]:
        """Memory bytes behind ``address .. address + length`` (indirect data resolved), cached
        until an Indirect Address register changes."""
        key = (address, length)
        targets = self._indirect_cache.get(key)
        if targets is None:
            targets = tuple(self._resolve(a) for a in range(address, address + length))
            self._indirect_cache[key] = targets
        return targets

    def read(self, address: int, length: int) -> tuple[int, bytes]:
        """Read ``length`` bytes; returns (status error byte, data)."""
        if length <= 0 or address < 0 or address + length > MEMORY_SIZE:
            return StatusError.ACCESS | self.alert, b""
        if not self._is_indirect(address, length):
            return self.alert, bytes(self.mem[address : address + length])
        mem = self.mem
        return self.alert, bytes([mem[t] if 0 <= t < MEMORY_SIZE else 0 for t in self._targets(address, length)])

    def write(self, address: int, data: bytes, now_s: float = 0.0) -> int:
        """Apply a write with the firmware's checks; returns the status error byte."""
        if not data or address < 0 or address + len(data) > MEMORY_SIZE:
            return StatusError.ACCESS | self.alert
        reg0 = self._reg_at_byte[address]
        if (reg0 is not None and reg0.address == address and reg0.size == len(data)
                and not self._is_indirect(address, len(data))):
            return self._write_register(reg0, bytes(data), now_s)
        targets = list(self._targets(address, len(data)))
        regs: dict[str, Register] = {}
        for t in targets:
            reg = self._reg_at_byte[t] if 0 <= t < MEMORY_SIZE else None
            if reg is None or not reg.writable:
                return StatusError.ACCESS | self.alert
            if reg.eeprom and self.torque_on:
                return StatusError.ACCESS | self.alert
            regs[reg.name] = reg
        new = bytearray(self.mem)
        for t, b in zip(targets, data):
            new[t] = b
        # value checks on complete registers
        for name, reg in regs.items():
            err = self._value_error(name, reg.decode(new[reg.address : reg.address + reg.size]))
            if err:
                return err
        was_on = self.torque_on
        self.mem[:] = new
        self._after_write(regs, was_on, now_s)
        return self.alert

    def _write_register(self, reg: Register, data: bytes, now_s: float) -> int:
        """Fast path of :meth:`write`: exactly one whole, directly addressed register."""
        if not reg.writable or (reg.eeprom and self.torque_on):
            return StatusError.ACCESS | self.alert
        err = self._value_error(reg.name, reg.decode(data))
        if err:
            return err
        was_on = self.torque_on
        self.mem[reg.address : reg.address + reg.size] = data
        self._after_write({reg.name: reg}, was_on, now_s)
        return self.alert

    def _value_error(self, name: str, value: int) -> int:
        """Status error byte if the firmware refuses ``value`` for register ``name``, else 0."""
        if name in _GOAL_REGISTERS and self.watchdog_tripped:
            return StatusError.DATA_RANGE | self.alert
        if name == "goal_position" and self.get("operating_mode") == 3:
            lo, hi = self.get("min_position_limit"), self.get("max_position_limit")
            if not lo <= value <= hi:
                return StatusError.DATA_LIMIT | self.alert
        if name == "operating_mode" and value not in self.table.operating_modes:
            return StatusError.DATA_RANGE | self.alert
        if name == "torque_enable":
            if value not in (0, 1):
                return StatusError.DATA_RANGE | self.alert
            if value == 1 and (self.hardware_error & self.get("shutdown")):
                return StatusError.RESULT_FAIL | self.alert
        if name == "bus_watchdog" and not (value == 0 or 1 <= value <= 127):
            return StatusError.DATA_RANGE | self.alert
        if name == "goal_pwm" and abs(value) > self.get("pwm_limit"):
            return StatusError.DATA_LIMIT | self.alert
        return 0

    def _after_write(self, regs: Mapping[str, Register], was_on: bool, now_s: float) -> None:
        if "bus_watchdog" in regs:
            if self.get("bus_watchdog") == 0:
                self.watchdog_tripped = False
            self.watchdog_last_feed_s = now_s
        if "torque_enable" in regs and self.torque_on and not was_on:
            self.watchdog_last_feed_s = now_s
        if any(name.startswith("indirect_address") for name in regs):
            self._indirect_cache.clear()

    # ---- time evolution ------------------------------------------------------------
    def feed_watchdog(self, now_s: float) -> None:
        self.watchdog_last_feed_s = now_s

    def watchdog_deadline(self) -> float | None:
        """Time [s] at which the watchdog trips if nothing arrives, or ``None`` if not armed."""
        if self.mem[64] != 1 or self.watchdog_tripped:
            return None
        value = self.get("bus_watchdog")
        if 1 <= value <= 127:
            return self.watchdog_last_feed_s + value * WATCHDOG_UNIT_S
        return None

    def trip_watchdog(self) -> None:
        _log.info("servo %d: bus watchdog tripped", self.id)
        self.watchdog_tripped = True
        self.watchdog_trips += 1
        self._set("bus_watchdog", -1)
        ticks = int(round(self.position_rad / RAD_PER_TICK)) + CENTER_TICKS
        self._set("goal_position", ticks)

    def command(self) -> ServoCommand:
        """The command this servo gives its shaft now."""
        get = self.get
        profile = get("profile_velocity")
        vmax = self.no_load_speed_rad_s
        if profile > 0:
            vmax = min(vmax, profile * VELOCITY_UNIT_RAD_S)
        pwm_limit = max(1, get("pwm_limit"))
        pwm_fraction = max(0.0, min(1.0, abs(get("goal_pwm")) / pwm_limit))
        if get("operating_mode") in (3, 4, 5):
            goal = (get("goal_position") - CENTER_TICKS) * RAD_PER_TICK
        else:
            goal = self.position_rad
        stiffness = self.stall_torque_nm / 0.22 * get("position_p_gain") / 800.0
        return ServoCommand(self.mem[64] == 1, goal, vmax, pwm_fraction, self.stall_torque_nm, stiffness)

    def apply_motion(self, motion: ServoMotion, dt_s: float, now_s: float, input_voltage_v: float,
                     heating_gain: float = 1.0) -> None:
        """Update present registers, temperature and hardware errors after a plant step."""
        mem, fields = self.mem, self._fields

        def put(name: str, value: int) -> None:
            _, writer, address, mask = fields[name]
            writer.pack_into(mem, address, value & mask)

        position, velocity, torque = motion.position_rad, motion.velocity_rad_s, motion.torque_nm
        self.position_rad = position
        put("present_position", int(round(position / RAD_PER_TICK)) + CENTER_TICKS)
        put("present_velocity", int(round(velocity / VELOCITY_UNIT_RAD_S)))
        table = self.table
        stall = self.stall_torque_nm
        if table.current_unit_a is not None:
            # linear torque-current model with 2.3 A at stall (XM430 datasheet)
            put("present_current", int(round(torque / stall * 2.3 / table.current_unit_a)))
        else:
            put("present_load", int(round(1000 * torque / stall)))
        put("present_pwm", int(round(885 * max(-1.0, min(1.0, torque / stall)))))
        put("moving", int(abs(velocity) > 0.02))
        put("realtime_tick", int((now_s - self.start_s) * 1000) % 32768)
        th = self.thermal
        if dt_s > 0:
            dT = heating_gain * th.heating_k_per_nm2_s * torque * torque - (
                self.temperature_c - th.ambient_c) / th.time_constant_s
            self.temperature_c += dT * dt_s
        put("present_temperature", max(0, min(255, int(round(self.temperature_c)))))
        v10 = input_voltage_v * 10
        put("present_input_voltage", int(round(v10)))
        bits = 0
        get = self.get
        if self.temperature_c > get("temperature_limit"):
            bits |= HardwareErrorBits.OVERHEATING
        if not get("min_voltage_limit") <= v10 <= get("max_voltage_limit"):
            bits |= HardwareErrorBits.INPUT_VOLTAGE
        if bits:
            self.raise_hardware_error(bits)

    def raise_hardware_error(self, bits: int) -> None:
        """Latch hardware error ``bits``; shut down if Shutdown says so."""
        if not bits:
            return
        new = self.hardware_error | bits
        if new != self.hardware_error:
            _log.info("servo %d: hardware error %s", self.id, HardwareErrorBits.describe(new))
        self.mem[70] = new
        if new & self.get("shutdown") and self.torque_on:
            self.mem[64] = 0

    def reboot(self, now_s: float, boot_time_s: float) -> None:
        """Reset RAM to defaults (EEPROM kept), clear errors; silent for ``boot_time_s``."""
        defaults = self.table.default_memory()
        self.mem[EEPROM_END:] = defaults[EEPROM_END:]
        self._indirect_cache.clear()
        self.mem[70] = 0
        ticks = int(round(self.position_rad / RAD_PER_TICK)) + CENTER_TICKS
        self._set("present_position", ticks)
        self._set("goal_position", ticks)
        self.watchdog_tripped = False
        self.registered = None
        self.boot_until_s = now_s + boot_time_s
        self.start_s = now_s
