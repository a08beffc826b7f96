"""One emulated Protocol 1.0 servo (AX, RX, MX with 1.0 firmware): the control table of
:mod:`drivers.control_table1` with the firmware rules the driver relies on.

- Alarms are bits of every status packet's error byte (:class:`drivers.protocol1.ErrorBits1`):
  input voltage and overheating while the condition lasts, overload latched until Torque Limit
  is written again. An alarm whose bit is in Alarm Shutdown (18) sets Torque Limit to 0: the
  shaft goes free until Torque Limit is written non-zero (e-manual, Torque Limit).
- Goal Position outside CW/CCW Angle Limit is refused with the Angle Limit bit; both limits 0
  is wheel mode (goal ignored). Values out of range are refused with the Range bit.
- The output is capped by Torque Limit / 1023; the position loop is the MX P Gain
  (Kp = P / 8 per tick of 1023) or the AX/RX Compliance Slope (full torque ``slope`` ticks off).
- No Bus Watchdog, no reboot; RESET restores the factory table (ID 1, default baud rate).
- EEPROM is writable with torque on (the 1.0 firmware does not refuse it).
"""

from __future__ import annotations

import logging
import struct

from drivers.control_table import ControlTable, Register
from drivers.control_table1 import DIRECTION_BIT, EEPROM_END_1
from drivers.mockbus.emulated_servo import ThermalModel, motor_figures
from drivers.mockbus.plant import ServoCommand, ServoMotion
from drivers.protocol1 import ErrorBits1

__all__ = ["EmulatedServo1"]

_log = logging.getLogger(__name__)
_STRUCT_CODE = {1: "B", 2: "H"}
_FULL_SCALE = 1023  # Torque Limit / Max Torque / Present Load full scale
_MX_KP_DIVISOR = 8.0  # e-manual MX (1.0): Kp = P Gain / 8


def _signed_magnitude(value: int) -> int:
    magnitude = min(abs(int(value)), 0x3FF)
    return magnitude | (DIRECTION_BIT if value < 0 else 0)


class EmulatedServo1:
    """State machine of one Protocol 1.0 servo on the emulated bus (arguments as
    :class:`drivers.mockbus.EmulatedServo`; ``baud_index`` is the 1.0 Baud Rate register value)."""

    def __init__(self, servo_id: int, table: ControlTable, *, baud_index: int = 1,
                 return_delay_units: int = 250, initial_position_ticks: int | None = None,
                 firmware_version: int | None = None, thermal: ThermalModel | None = None) -> None:
        self.table = table
        self.stall_torque_nm, self.no_load_speed_rad_s = motor_figures(table.model)
        self.thermal = thermal or ThermalModel()
        self._reg_at_byte: list[Register | None] = [None] * table.memory_size
        self._fields: dict[str, tuple[struct.Struct, int]] = {}
        for reg in table.registers.values():
            for a in range(reg.address, reg.address + reg.size):
                self._reg_at_byte[a] = reg
            code = _STRUCT_CODE[reg.size]
            self._fields[reg.name] = (struct.Struct("<" + (code.lower() if reg.signed else code)), reg.address)
        self._mx = table.has("p_gain")
        self.mem = table.default_memory()
        self._set("id", servo_id)
        self._set("baud_rate", baud_index)
        self._set("return_delay_time", return_delay_units)
        if firmware_version is not None:
            self._set("firmware_version", firmware_version)
        ticks = table.center_ticks if initial_position_ticks is None else initial_position_ticks
        self.position_rad = (ticks - table.center_ticks) * table.rad_per_tick
        self._set("present_position", ticks)
        self._set("goal_position", ticks)
        self.temperature_c = self.thermal.ambient_c
        self.live_alarms = 0  # input voltage, overheating: while the condition lasts
        self.latched_alarms = 0  # overload: until Torque Limit is written again
        self.watchdog_last_feed_s = 0.0  # no Bus Watchdog on 1.0: kept for the bus's bookkeeping
        self.watchdog_tripped = False
        self.watchdog_trips = 0
        self.boot_until_s = 0.0
        self.registered: tuple[int, bytes] | None = None
        self.start_s = 0.0
        self.shutdowns = 0  # alarm shutdowns since power-on (for tests and tools)

    # ---- raw memory ----------------------------------------------------------------
    def _set(self, name: str, value: int) -> None:
        codec, address = self._fields[name]
        size = codec.size
        self.mem[address : address + size] = (int(value) & ((1 << (8 * size)) - 1)).to_bytes(size, "little")

    def get(self, name: str) -> int:
        """Integer value of register ``name``."""
        try:
            codec, address = self._fields[name]
        except KeyError:
            self.table[name]  # raises, naming the valid registers
            raise
        return codec.unpack_from(self.mem, address)[0]

    @property
    def id(self) -> int:
        return self.mem[3]

    @property
    def torque_on(self) -> bool:
        return self.mem[24] == 1

    @property
    def hardware_error(self) -> int:
        """The alarm bits present now (the hardware part of the status error byte)."""
        return self.live_alarms | self.latched_alarms

    @property
    def alert(self) -> int:
        """The error byte's alarm bits, sent with every status."""
        return self.hardware_error

    @property
    def baud_index(self) -> int:
        return self.mem[4]

    # ---- reads and writes ------------------------------------------------------------
    def read(self, address: int, length: int) -> tuple[int, bytes]:
        """Read ``length`` bytes; returns (status error byte, data)."""
        if length <= 0 or address < 0 or address + length > self.table.memory_size:
            return ErrorBits1.RANGE | self.alert, b""
        return self.alert, bytes(self.mem[address : address + length])

    def write(self, address: int, data: bytes, now_s: float = 0.0) -> int:
        """Apply a write with the firmware's checks; returns the status error byte."""
        if not data or address < 0 or address + len(data) > self.table.memory_size:
            return ErrorBits1.RANGE | self.alert
        regs: dict[str, Register] = {}
        for a in range(address, address + len(data)):
            reg = self._reg_at_byte[a]
            if reg is None or not reg.writable:
                return ErrorBits1.RANGE | self.alert
            regs[reg.name] = reg
        new = bytearray(self.mem)
        new[address : address + len(data)] = data
        for name, reg in regs.items():
            err = self._value_error(name, reg.decode(new[reg.address : reg.address + reg.size]), new)
            if err:
                return err | self.alert
        self.mem[:] = new
        if "torque_limit" in regs and self.get("torque_limit") > 0:
            self.latched_alarms = 0
        return self.alert

    def _value_error(self, name: str, value: int, new: bytearray) -> int:
        table = self.table
        if name == "goal_position":
            if value > table.max_ticks:
                return ErrorBits1.RANGE
            cw = int.from_bytes(new[6:8], "little")
            ccw = int.from_bytes(new[8:10], "little")
            if (cw or ccw) and not cw <= value <= ccw:
                return ErrorBits1.ANGLE_LIMIT
        if name in ("cw_angle_limit", "ccw_angle_limit") and value > table.max_ticks:
            return ErrorBits1.RANGE
        if name in ("torque_limit", "max_torque", "punch") and value > _FULL_SCALE:
            return ErrorBits1.RANGE
        if name == "moving_speed" and value > 2047:
            return ErrorBits1.RANGE
        if name in ("torque_enable", "led", "lock") and value not in (0, 1):
            return ErrorBits1.RANGE
        if name == "status_return_level" and value > 2:
            return ErrorBits1.RANGE
        if name == "id" and value > 253:
            return ErrorBits1.RANGE
        return 0

    def reset(self) -> None:
        """RESET: the factory table (ID 1, default baud rate), shaft where it is."""
        ticks = self.get("present_position")
        self.mem[:] = self.table.default_memory()
        self._set("present_position", ticks)
        self._set("goal_position", ticks)
        self.latched_alarms = 0
        self.registered = None

    # ---- time evolution (the bus's interface, as EmulatedServo) ------------------------
    def feed_watchdog(self, now_s: float) -> None:
        self.watchdog_last_feed_s = now_s

    def watchdog_deadline(self) -> float | None:
        return None  # 1.0 firmware has no Bus Watchdog

    def trip_watchdog(self) -> None:  # pragma: no cover - never due
        pass

    def command(self) -> ServoCommand:
        """The command this servo gives its shaft now."""
        table = self.table
        get = self.get
        vmax = self.no_load_speed_rad_s
        speed = get("moving_speed") & 0x3FF
        if speed > 0:
            vmax = min(vmax, speed * table.velocity_unit_rad_s)
        cap = max(0.0, min(1.0, get("torque_limit") / _FULL_SCALE))
        wheel = get("cw_angle_limit") == 0 and get("ccw_angle_limit") == 0
        goal = self.position_rad if wheel else (get("goal_position") - table.center_ticks) * table.rad_per_tick
        if self._mx:
            kp = get("p_gain") / _MX_KP_DIVISOR / _FULL_SCALE  # output fraction per tick
            stiffness = self.stall_torque_nm * kp / table.rad_per_tick
        else:
            slope = max(1, min(get("cw_compliance_slope"), get("ccw_compliance_slope")))
            stiffness = self.stall_torque_nm / (slope * table.rad_per_tick)
        return ServoCommand(self.torque_on and cap > 0, goal, vmax, cap, self.stall_torque_nm, stiffness)

    def apply_motion(self, motion: ServoMotion, dt_s: float, now_s: float, input_voltage_v: float,
                     heating_gain: float = 1.0) -> None:
        """Update present registers, temperature and alarms after a plant step."""
        table = self.table
        position, velocity, torque = motion.position_rad, motion.velocity_rad_s, motion.torque_nm
        self.position_rad = position
        ticks = int(round(position / table.rad_per_tick)) + table.center_ticks
        self._set("present_position", max(0, min(table.max_ticks, ticks)))
        self._set("present_speed", _signed_magnitude(round(velocity / table.velocity_unit_rad_s)))
        self._set("present_load", _signed_magnitude(round(_FULL_SCALE * torque / self.stall_torque_nm)))
        self._set("moving", int(abs(velocity) > 0.02))
        if self._mx:
            self._set("realtime_tick", int((now_s - self.start_s) * 1000) % 32768)
        th = self.thermal
        if dt_s > 0:
            dT = heating_gain * th.heating_k_per_nm2_s * torque * torque - (
                self.temperature_c - th.ambient_c) / th.time_constant_s
            self.temperature_c += dT * dt_s
        self._set("present_temperature", max(0, min(255, int(round(self.temperature_c)))))
        v10 = int(round(input_voltage_v * 10))
        self._set("present_voltage", max(0, min(255, v10)))
        live = 0
        if self.temperature_c > self.get("temperature_limit"):
            live |= ErrorBits1.OVERHEATING
        if not self.get("min_voltage_limit") <= v10 <= self.get("max_voltage_limit"):
            live |= ErrorBits1.INPUT_VOLTAGE
        self._alarm(live, latched=False)

    def raise_hardware_error(self, bits: int) -> None:
        """An alarm (``ErrorBits1`` bits; the 2.0 Hardware Error bits for voltage, overheating
        and overload have the same values): latched, and a shutdown where Alarm Shutdown says so."""
        self._alarm(bits & ErrorBits1.HARDWARE, latched=True)

    def _alarm(self, bits: int, *, latched: bool) -> None:
        before = self.hardware_error
        if latched:
            self.latched_alarms |= bits
        else:
            self.live_alarms = bits
        new = self.hardware_error
        if new & ~before:
            _log.info("servo %d: alarm %s", self.id, ErrorBits1.describe(new))
            if new & ~before & self.get("alarm_shutdown") and self.get("torque_limit"):
                self._set("torque_limit", 0)  # the shaft goes free
                self.shutdowns += 1

    def reboot(self, now_s: float, boot_time_s: float) -> None:
        """Power cycle: RAM back to defaults (EEPROM kept), alarms cleared; silent for ``boot_time_s``."""
        defaults = self.table.default_memory()
        self.mem[EEPROM_END_1:] = defaults[EEPROM_END_1:]
        ticks = int(round(self.position_rad / self.table.rad_per_tick)) + self.table.center_ticks
        self._set("present_position", ticks)
        self._set("goal_position", ticks)
        self.latched_alarms = 0
        self.registered = None
        self.boot_until_s = now_s + boot_time_s
        self.start_s = now_s
