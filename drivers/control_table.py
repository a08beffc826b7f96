"""Control tables of the supported servo models, as data.

Addresses and sizes follow the ROBOTIS e-manual pages of each model (X series, Protocol 2.0;
MX-28 with the "(2.0)" firmware inherits the X layout). See ``../shared/facts/dynamixel.md``.
Addresses below 64 are EEPROM: writable only with Torque Enable = 0.

Register layout and factory defaults only: a model's physical figures (stall torque, no-load
speed, gear ratio, each with its datasheet source) are the servo catalog's
(``configs/servos/catalog.toml``, read by :mod:`robot_files.servo_catalog`); the emulator takes
its load model from there.

Units of raw values (what ``drivers`` converts, nothing else does):
    position: 4096 ticks per revolution, 2048 = centre.
    velocity: 0.229 rev/min per unit.
    current: 2.69 mA per unit (XM430-W350, XM540-W270); XL430-W250 and MX-28(2.0) report
        Present Load in 0.1 % of the maximum instead.
    voltage: 0.1 V per unit; temperature: 1 degC per unit; bus watchdog: 20 ms per unit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

from drivers.errors import ControlTableError

__all__ = [
    "BAUD_RATE_BY_INDEX",
    "BAUD_INDEX_BY_RATE",
    "Register",
    "ControlTable",
    "control_table",
    "model_for_number",
    "SUPPORTED_MODELS",
    "SUPPORTED_MODELS_1",
    "EEPROM_END",
    "MEMORY_SIZE",
    "TICKS_PER_REV",
    "CENTER_TICKS",
    "RAD_PER_TICK",
    "VELOCITY_UNIT_RAD_S",
    "VOLTAGE_UNIT_V",
    "WATCHDOG_UNIT_S",
    "RETURN_DELAY_UNIT_S",
    "HardwareErrorBits",
    "INDIRECT_ADDRESS_1",
    "INDIRECT_DATA_1",
    "INDIRECT_COUNT",
]

EEPROM_END = 64  # addresses < 64 are EEPROM (write-protected while torque is on)
MEMORY_SIZE = 662  # bytes: up to Indirect Data 56 (634 + 28)
TICKS_PER_REV = 4096
CENTER_TICKS = 2048
# Baud Rate register (address 8) value -> bit/s, X-series e-manual
BAUD_RATE_BY_INDEX: Mapping[int, int] = MappingProxyType({0: 9600, 1: 57600, 2: 115200, 3: 1_000_000, 4: 2_000_000,
                                                         5: 3_000_000, 6: 4_000_000, 7: 4_500_000})
BAUD_INDEX_BY_RATE: Mapping[int, int] = MappingProxyType({rate: i for i, rate in BAUD_RATE_BY_INDEX.items()})
RAD_PER_TICK = 2.0 * math.pi / TICKS_PER_REV  # [rad/tick]
VELOCITY_UNIT_RAD_S = 0.229 * 2.0 * math.pi / 60.0  # [rad/s per unit] (0.229 rev/min)
VOLTAGE_UNIT_V = 0.1  # [V per unit]
WATCHDOG_UNIT_S = 0.020  # [s per unit] Bus Watchdog
RETURN_DELAY_UNIT_S = 2e-6  # [s per unit] Return Delay Time
INDIRECT_ADDRESS_1 = 168  # Indirect Address 1..28 at 168 + 2k (2 bytes each)
INDIRECT_DATA_1 = 224  # Indirect Data 1..28 at 224 + k (1 byte each)
INDIRECT_COUNT = 28


class HardwareErrorBits:
    """Bits of the Hardware Error Status register (address 70): flags to test, not an exception."""

    INPUT_VOLTAGE = 0x01
    OVERHEATING = 0x04
    MOTOR_ENCODER = 0x08
    ELECTRICAL_SHOCK = 0x10
    OVERLOAD = 0x20

    NAMES = {
        0x01: "input voltage",
        0x04: "overheating",
        0x08: "motor encoder",
        0x10: "electrical shock",
        0x20: "overload",
    }

    @classmethod
    def describe(cls, bits: int) -> str:
        """E.g. ``"overheating, overload"``; ``"none"`` for 0."""
        names = [name for bit, name in cls.NAMES.items() if bits & bit]
        return ", ".join(names) or "none"


@dataclass(frozen=True)
class Register:
    """One control-table entry.

    Attributes:
        name: snake_case name, e.g. ``"goal_position"``.
        address: byte address.
        size: 1, 2 or 4 bytes (little endian).
        writable: RW (True) or R (False).
        signed: two's complement.
        eeprom_end: first RAM address of the table it belongs to (64 on the X series, 24 on the
            Protocol 1.0 models).
    """

    name: str
    address: int
    size: int
    writable: bool = True
    signed: bool = False
    eeprom_end: int = EEPROM_END

    @property
    def eeprom(self) -> bool:
        return self.address < self.eeprom_end

    def encode(self, value: int) -> bytes:
        """Raw little-endian bytes of ``value`` (wrapped to the register width)."""
        mask = (1 << (8 * self.size)) - 1
        return (int(value) & mask).to_bytes(self.size, "little")

    def decode(self, data: bytes) -> int:
        """Integer value of ``data`` (exactly ``size`` bytes)."""
        return int.from_bytes(data, "little", signed=self.signed)


def _x_series_rows() -> list[Register]:
    R = Register
    rows = [
        R("model_number", 0, 2, False),
        R("model_information", 2, 4, False),
        R("firmware_version", 6, 1, False),
        R("id", 7, 1),
        R("baud_rate", 8, 1),
        R("return_delay_time", 9, 1),
        R("drive_mode", 10, 1),
        R("operating_mode", 11, 1),
        R("secondary_id", 12, 1),
        R("protocol_type", 13, 1),
        R("homing_offset", 20, 4, signed=True),
        R("moving_threshold", 24, 4),
        R("temperature_limit", 31, 1),
        R("max_voltage_limit", 32, 2),
        R("min_voltage_limit", 34, 2),
        R("pwm_limit", 36, 2),
        R("current_limit", 38, 2),
        R("velocity_limit", 44, 4),
        R("max_position_limit", 48, 4),
        R("min_position_limit", 52, 4),
        R("shutdown", 63, 1),
        R("torque_enable", 64, 1),
        R("led", 65, 1),
        R("status_return_level", 68, 1),
        R("registered_instruction", 69, 1, False),
        R("hardware_error_status", 70, 1, False),
        R("velocity_i_gain", 76, 2),
        R("velocity_p_gain", 78, 2),
        R("position_d_gain", 80, 2),
        R("position_i_gain", 82, 2),
        R("position_p_gain", 84, 2),
        R("feedforward_2nd_gain", 88, 2),
        R("feedforward_1st_gain", 90, 2),
        R("bus_watchdog", 98, 1, signed=True),
        R("goal_pwm", 100, 2, signed=True),
        R("goal_current", 102, 2, signed=True),
        R("goal_velocity", 104, 4, signed=True),
        R("profile_acceleration", 108, 4),
        R("profile_velocity", 112, 4),
        R("goal_position", 116, 4, signed=True),
        R("realtime_tick", 120, 2, False),
        R("moving", 122, 1, False),
        R("moving_status", 123, 1, False),
        R("present_pwm", 124, 2, False, signed=True),
        R("present_current", 126, 2, False, signed=True),
        R("present_velocity", 128, 4, False, signed=True),
        R("present_position", 132, 4, False, signed=True),
        R("velocity_trajectory", 136, 4, False, signed=True),
        R("position_trajectory", 140, 4, False, signed=True),
        R("present_input_voltage", 144, 2, False),
        R("present_temperature", 146, 1, False),
    ]
    for k in range(INDIRECT_COUNT):
        rows.append(R(f"indirect_address_{k + 1}", INDIRECT_ADDRESS_1 + 2 * k, 2))
        rows.append(R(f"indirect_data_{k + 1}", INDIRECT_DATA_1 + k, 1))
    for k in range(INDIRECT_COUNT):
        rows.append(R(f"indirect_address_{k + 29}", 578 + 2 * k, 2))
        rows.append(R(f"indirect_data_{k + 29}", 634 + k, 1))
    return rows


@dataclass(frozen=True)
class ControlTable:
    """The register table of one servo model plus its factory defaults and units.

    Attributes:
        model: model name as written in the servo map, e.g. ``"XM430-W350"``.
        model_number: value of register ``model_number``.
        registers: name -> :class:`Register` (read-only mapping).
        defaults: name -> factory default raw value (registers not listed default to 0).
        current_unit_a: [A per unit] of ``present_current``, or ``None`` when the model reports
            Present Load (0.1 % units) at that address instead.
        operating_modes: the values ``operating_mode`` accepts.
        fast_sync_read_min_firmware: first firmware version answering Fast Sync Read.
        protocol: the Dynamixel protocol this table is spoken in (2.0, or 1.0 for the AX, RX
            and MX (1.0 firmware) tables of :mod:`drivers.control_table1`).
        center_ticks: position value of the shaft's zero (2048 on 4096-tick models, 512 on AX/RX).
        max_ticks: highest position value (4095, or 1023 on AX/RX).
        rad_per_tick: [rad] per position unit (2 pi / 4096; 300 deg / 1023 on AX/RX).
        velocity_unit_rad_s: [rad/s] per velocity unit (0.229 rev/min on the X series).
        bulk_read: the model answers BULK_READ (every 2.0 model; only the MX series on 1.0).
        memory_size: bytes of the emulated memory image.
        source: the e-manual page of the table.
    """

    model: str
    model_number: int
    registers: Mapping[str, Register]
    defaults: Mapping[str, int]
    current_unit_a: float | None
    operating_modes: frozenset[int]
    fast_sync_read_min_firmware: int = 45
    protocol: float = 2.0
    center_ticks: int = CENTER_TICKS
    max_ticks: int = TICKS_PER_REV - 1
    rad_per_tick: float = RAD_PER_TICK
    velocity_unit_rad_s: float = VELOCITY_UNIT_RAD_S
    bulk_read: bool = True
    memory_size: int = MEMORY_SIZE
    source: str = ""
    _by_address: Mapping[int, Register] = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "_by_address", MappingProxyType({r.address: r for r in self.registers.values()})
        )

    def __getitem__(self, name: str) -> Register:
        try:
            return self.registers[name]
        except KeyError:
            raise ControlTableError(
                f"{self.model} has no register {name!r}",
                hint="valid names: " + ", ".join(n for n in self.registers if not n.startswith("indirect")),
            ) from None

    def has(self, name: str) -> bool:
        return name in self.registers

    def at(self, address: int) -> Register | None:
        """The register starting at ``address``, if any."""
        return self._by_address.get(address)

    def default_memory(self) -> bytearray:
        """A full memory image (``memory_size`` bytes) holding the factory defaults."""
        mem = bytearray(self.memory_size)
        for name, value in self.defaults.items():
            reg = self.registers[name]
            mem[reg.address : reg.address + reg.size] = reg.encode(value)
        return mem


def _table(
    model: str,
    model_number: int,
    *,
    drop: tuple[str, ...] = (),
    rename: Mapping[str, str] | None = None,
    defaults: Mapping[str, int],
    current_unit_a: float | None,
    operating_modes: frozenset[int],
) -> ControlTable:
    rows = {}
    for r in _x_series_rows():
        if r.name in drop:
            continue
        name = (rename or {}).get(r.name, r.name)
        rows[name] = Register(name, r.address, r.size, r.writable, r.signed)
    base_defaults = {
        "model_number": model_number,
        "firmware_version": 46,
        "id": 1,
        "baud_rate": 1,
        "return_delay_time": 250,
        "operating_mode": 3,
        "protocol_type": 2,
        "secondary_id": 255,
        "moving_threshold": 10,
        "temperature_limit": 80,
        "max_voltage_limit": 160,
        "min_voltage_limit": 95,
        "pwm_limit": 885,
        "velocity_limit": 200,
        "max_position_limit": 4095,
        "min_position_limit": 0,
        "shutdown": 52,
        "status_return_level": 2,
        "goal_pwm": 885,
        "present_input_voltage": 120,
        "present_temperature": 30,
        "present_position": CENTER_TICKS,
        "goal_position": CENTER_TICKS,
    }
    base_defaults.update(defaults)
    return ControlTable(
        model=model,
        model_number=model_number,
        registers=MappingProxyType(rows),
        defaults=MappingProxyType({k: v for k, v in base_defaults.items() if k in rows}),
        current_unit_a=current_unit_a,
        operating_modes=operating_modes,
    )


_TABLES: dict[str, ControlTable] = {
    t.model: t
    for t in (
        _table(
            "XM430-W350", 1020,
            defaults={"current_limit": 1193, "goal_current": 1193, "position_p_gain": 800,
                      "velocity_i_gain": 1920, "velocity_p_gain": 100},
            current_unit_a=0.00269, operating_modes=frozenset({0, 1, 3, 4, 5, 16}),
        ),
        _table(
            "XM540-W270", 1120,
            defaults={"current_limit": 2047, "goal_current": 2047, "position_p_gain": 900,
                      "velocity_i_gain": 1920, "velocity_p_gain": 100},
            current_unit_a=0.00269, operating_modes=frozenset({0, 1, 3, 4, 5, 16}),
        ),
        _table(
            "XL430-W250", 1060,
            drop=("current_limit", "goal_current"), rename={"present_current": "present_load"},
            defaults={"position_p_gain": 640, "position_d_gain": 4000, "velocity_limit": 265,
                      "velocity_i_gain": 1000, "velocity_p_gain": 100, "max_voltage_limit": 140,
                      "min_voltage_limit": 60, "temperature_limit": 72},
            current_unit_a=None, operating_modes=frozenset({1, 3, 4, 16}),
        ),
        _table(
            "MX-28(2.0)", 30,
            drop=("current_limit", "goal_current"), rename={"present_current": "present_load"},
            defaults={"position_p_gain": 850, "velocity_limit": 230, "velocity_i_gain": 1920,
                      "velocity_p_gain": 100, "max_voltage_limit": 160, "min_voltage_limit": 95},
            current_unit_a=None, operating_modes=frozenset({1, 3, 4, 16}),
        ),
        # Model numbers: ROBOTIS e-manual control tables (XH430-W350 1000, XH540-W270 1100,
        # MX-64(2.0) 311 = 0x0137, MX-106(2.0) 321 = 0x0141; the DYNAMIXEL SDK's model lists agree).
        # Current units: XH430 1.34 mA, XH540 2.69 mA, MX(2.0) 3.36 mA.
        _table(
            "XH430-W350", 1000,
            defaults={"current_limit": 648, "goal_current": 648, "position_p_gain": 900,
                      "velocity_i_gain": 1920, "velocity_p_gain": 100},
            current_unit_a=0.00134, operating_modes=frozenset({0, 1, 3, 4, 5, 16}),
        ),
        _table(
            "XH540-W270", 1100,
            defaults={"current_limit": 2047, "goal_current": 2047, "position_p_gain": 800,
                      "velocity_i_gain": 1920, "velocity_p_gain": 100},
            current_unit_a=0.00269, operating_modes=frozenset({0, 1, 3, 4, 5, 16}),
        ),
        _table(
            "MX-64(2.0)", 311,
            defaults={"current_limit": 1941, "goal_current": 1941, "position_p_gain": 850,
                      "velocity_limit": 285, "velocity_i_gain": 1920, "velocity_p_gain": 100},
            current_unit_a=0.00336, operating_modes=frozenset({0, 1, 3, 4, 5, 16}),
        ),
        _table(
            "MX-106(2.0)", 321,
            defaults={"current_limit": 2047, "goal_current": 2047, "position_p_gain": 850,
                      "velocity_limit": 210, "velocity_i_gain": 1920, "velocity_p_gain": 100},
            current_unit_a=0.00336, operating_modes=frozenset({0, 1, 3, 4, 5, 16}),
        ),
    )
}
# the servo catalog's names for the Protocol 2.0 firmware of the MX series
_ALIASES = {"MX-28": "MX-28(2.0)", "MX-64": "MX-64(2.0)", "MX-106": "MX-106(2.0)"}

SUPPORTED_MODELS: tuple[str, ...] = tuple(_TABLES)

from drivers.control_table1 import ALIASES_1, TABLES_1  # noqa: E402  (the 1.0 tables build on Register above)

SUPPORTED_MODELS_1: tuple[str, ...] = tuple(TABLES_1)


def control_table(model: str, protocol: float = 2.0) -> ControlTable:
    """The :class:`ControlTable` of ``model`` (e.g. ``"XM430-W350"``) on a ``protocol`` bus.

    On a Protocol 1.0 bus ``MX-28`` means the MX-28 with its 1.0 firmware (``MX-28(1.0)``), on
    a 2.0 bus the 2.0 firmware; the AX and RX series speak 1.0 only, the X series 2.0 only here.

    Raises:
        ControlTableError: unknown model, or one that does not speak ``protocol`` (the message
            lists the supported ones).
    """
    if protocol == 1.0:
        table = TABLES_1.get(ALIASES_1.get(model, model))
        if table is not None:
            return table
        if _TABLES.get(_ALIASES.get(model, model)) is not None:
            raise ControlTableError(f"servo model {model!r} is driven over Protocol 2.0 only",
                                    hint="Protocol 1.0 models: " + ", ".join(SUPPORTED_MODELS_1)
                                    + "; or set [bus] protocol = 2.0")
        raise ControlTableError(f"unknown servo model {model!r}",
                                hint="Protocol 1.0 models: " + ", ".join(SUPPORTED_MODELS_1))
    try:
        return _TABLES[_ALIASES.get(model, model)]
    except KeyError:
        if model in TABLES_1 or model in ALIASES_1.values():
            raise ControlTableError(f"servo model {model!r} speaks Protocol 1.0",
                                    hint="set [bus] protocol = 1.0 in servos.toml") from None
        raise ControlTableError(
            f"unknown servo model {model!r}", hint="supported models: " + ", ".join(SUPPORTED_MODELS)
        ) from None


def model_for_number(model_number: int, protocol: float = 2.0) -> ControlTable | None:
    """The table of ``protocol`` whose ``model_number`` matches, or ``None``."""
    for table in (TABLES_1 if protocol == 1.0 else _TABLES).values():
        if table.model_number == model_number:
            return table
    return None
