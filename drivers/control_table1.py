"""Control tables of the Protocol 1.0 models, as data: AX-12A, AX-18A, RX-28, RX-64 and the MX
series with its 1.0 firmware (MX-28, MX-64, MX-106).

Sources (ROBOTIS e-manual, one page per model, "Control Table"):
    AX-12A  https://emanual.robotis.com/docs/en/dxl/ax/ax-12a/#control-table
    AX-18A  https://emanual.robotis.com/docs/en/dxl/ax/ax-18a/#control-table
    RX-28   https://emanual.robotis.com/docs/en/dxl/rx/rx-28/#control-table
    RX-64   https://emanual.robotis.com/docs/en/dxl/rx/rx-64/#control-table
    MX-28   https://emanual.robotis.com/docs/en/dxl/mx/mx-28/#control-table  (1.0 firmware)
    MX-64   https://emanual.robotis.com/docs/en/dxl/mx/mx-64/#control-table  (1.0 firmware)
    MX-106  https://emanual.robotis.com/docs/en/dxl/mx/mx-106/#control-table (1.0 firmware)

Every model shares one layout up to address 49: EEPROM 0..23 (the 1.0 firmware accepts EEPROM
writes with torque on; the driver still writes them with torque off, as on 2.0), RAM from 24
(Torque Enable). The difference at 26..29: AX/RX have
Compliance Margins (26, 27) and Slopes (28, 29), the MX series D, I, P Gain (26, 27, 28).
The MX series adds Multi Turn Offset (20), Resolution Divider (22), Realtime Tick (50),
Goal Acceleration (73), and on MX-64/MX-106 Current (68), Torque Control Mode (70), Goal
Torque (71).

Units of raw values (what ``drivers`` converts, nothing else does):
    position: AX/RX 0..1023 over 300 deg (512 = centre); MX 0..4095 over 360 deg (2048 = centre).
    speed: Moving Speed / Present Speed, 0..1023 with bit 10 the direction (set: CW, negative);
        0.111 rev/min per unit on AX/RX, 0.114 rev/min on MX.
    load: Present Load, 0..1023 with bit 10 the direction, 0.1 % of the maximum torque.
    torque limits: Max Torque (EEPROM 14) and Torque Limit (RAM 34), 0..1023 of the maximum.
        An alarm in Alarm Shutdown sets Torque Limit to 0 (the shaft goes free); writing it
        non-zero again gives the torque back (e-manual, Torque Limit).
    voltage: 0.1 V per unit; temperature: 1 degC per unit; return delay: 2 us per unit.
There is no Bus Watchdog, no Hardware Error Status register (the alarms arrive as bits of every
status packet's error byte, :class:`drivers.protocol1.ErrorBits1`) and no Reboot instruction.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from types import MappingProxyType
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from drivers.control_table import ControlTable, Register

__all__ = [
    "EEPROM_END_1",
    "MEMORY_SIZE_1",
    "BAUD_RATE_BY_INDEX_1",
    "BAUD_INDEX_BY_RATE_1",
    "DIRECTION_BIT",
    "TABLES_1",
    "ALIASES_1",
    "decode_signed_magnitude",
]

EEPROM_END_1 = 24  # addresses < 24 are EEPROM
MEMORY_SIZE_1 = 74  # bytes: through Goal Acceleration (73)
DIRECTION_BIT = 0x400  # bit 10 of Present Speed / Present Load / Moving Speed: CW (negative)
# Baud Rate register (address 4) value -> bit/s: 2 000 000 / (value + 1), the nominal rates the
# host opens (0 = 2 Mbps by the formula); MX adds 250 / 251 / 252 = 2.25 / 2.5 / 3 Mbps (e-manual, Baud Rate).
BAUD_RATE_BY_INDEX_1: Mapping[int, int] = MappingProxyType({
    0: 2_000_000, 1: 1_000_000, 3: 500_000, 4: 400_000, 7: 250_000, 9: 200_000, 16: 115_200, 34: 57_600, 103: 19_200,
    207: 9_600, 250: 2_250_000, 251: 2_500_000, 252: 3_000_000})
BAUD_INDEX_BY_RATE_1: Mapping[int, int] = MappingProxyType({r: i for i, r in BAUD_RATE_BY_INDEX_1.items()})
_AX_RAD_PER_TICK = math.radians(300.0) / 1023  # [rad] per position unit on AX/RX
_MX_RAD_PER_TICK = 2.0 * math.pi / 4096  # [rad] per position unit on MX
_RPM = 2.0 * math.pi / 60.0  # [rad/s] per rev/min


def decode_signed_magnitude(raw: int) -> int:
    """Present Speed / Present Load value as a signed number: bit 10 set = CW = negative."""
    magnitude = raw & 0x3FF
    return -magnitude if raw & DIRECTION_BIT else magnitude


def _rows(mx: bool, current: bool) -> list["Register"]:
    from drivers.control_table import Register

    def R(name: str, address: int, size: int, writable: bool = True, signed: bool = False) -> Register:
        return Register(name, address, size, writable, signed, eeprom_end=EEPROM_END_1)

    rows = [
        R("model_number", 0, 2, False),
        R("firmware_version", 2, 1, False),
        R("id", 3, 1),
        R("baud_rate", 4, 1),
        R("return_delay_time", 5, 1),
        R("cw_angle_limit", 6, 2),
        R("ccw_angle_limit", 8, 2),
        R("temperature_limit", 11, 1),
        R("min_voltage_limit", 12, 1),
        R("max_voltage_limit", 13, 1),
        R("max_torque", 14, 2),
        R("status_return_level", 16, 1),
        R("alarm_led", 17, 1),
        R("alarm_shutdown", 18, 1),
        R("torque_enable", 24, 1),
        R("led", 25, 1),
        R("goal_position", 30, 2),
        R("moving_speed", 32, 2),
        R("torque_limit", 34, 2),
        R("present_position", 36, 2, False),
        R("present_speed", 38, 2, False),
        R("present_load", 40, 2, False),
        R("present_voltage", 42, 1, False),
        R("present_temperature", 43, 1, False),
        R("registered", 44, 1, False),
        R("moving", 46, 1, False),
        R("lock", 47, 1),
        R("punch", 48, 2),
    ]
    if mx:
        rows += [
            R("multi_turn_offset", 20, 2, signed=True),
            R("resolution_divider", 22, 1),
            R("d_gain", 26, 1),
            R("i_gain", 27, 1),
            R("p_gain", 28, 1),
            R("realtime_tick", 50, 2, False),
            R("goal_acceleration", 73, 1),
        ]
    else:
        rows += [
            R("cw_compliance_margin", 26, 1),
            R("ccw_compliance_margin", 27, 1),
            R("cw_compliance_slope", 28, 1),
            R("ccw_compliance_slope", 29, 1),
        ]
    if current:
        rows += [
            R("current", 68, 2, False),
            R("torque_control_mode_enable", 70, 1),
            R("goal_torque", 71, 2),
        ]
    return sorted(rows, key=lambda r: r.address)


def _table(model: str, model_number: int, *, family: str, defaults: Mapping[str, int], source: str,
           current: bool = False) -> "ControlTable":
    from drivers.control_table import ControlTable

    mx = family == "mx"
    rows = {r.name: r for r in _rows(mx, current)}
    center = 2048 if mx else 512
    base = {
        "model_number": model_number,
        "firmware_version": 39 if mx else 24,
        "id": 1,
        "baud_rate": 34,
        "return_delay_time": 250,
        "cw_angle_limit": 0,
        "ccw_angle_limit": 4095 if mx else 1023,
        "temperature_limit": 80 if mx else 70,
        "min_voltage_limit": 60,
        "max_voltage_limit": 160 if mx else 140,
        "max_torque": 1023,
        "status_return_level": 2,
        "alarm_led": 36,
        "alarm_shutdown": 36,
        "torque_limit": 1023,
        "present_position": center,
        "goal_position": center,
        "present_voltage": 120,
        "present_temperature": 30,
        "punch": 0 if mx else 32,
    }
    if mx:
        base |= {"resolution_divider": 1, "p_gain": 32, "i_gain": 0, "d_gain": 0}
    else:
        base |= {"cw_compliance_margin": 1, "ccw_compliance_margin": 1, "cw_compliance_slope": 32,
                 "ccw_compliance_slope": 32}
    base |= dict(defaults)
    return ControlTable(
        model=model,
        model_number=model_number,
        registers=MappingProxyType(rows),
        defaults=MappingProxyType({k: v for k, v in base.items() if k in rows}),
        current_unit_a=None,  # Present Load (0.1 %) only; MX-64/106 Current (68) is not read
        operating_modes=frozenset(),  # joint mode is set by the angle limits, not a register
        fast_sync_read_min_firmware=1 << 30,  # no Fast Sync Read on 1.0
        protocol=1.0,
        center_ticks=center,
        max_ticks=4095 if mx else 1023,
        rad_per_tick=_MX_RAD_PER_TICK if mx else _AX_RAD_PER_TICK,
        velocity_unit_rad_s=(0.114 if mx else 0.111) * _RPM,
        bulk_read=mx,
        memory_size=MEMORY_SIZE_1,
        source=source,
    )


_EMANUAL = "https://emanual.robotis.com/docs/en/dxl/"
# Model numbers: the e-manual control tables (AX-12A 12, AX-18A 18, RX-28 28, RX-64 64, MX-28 29,
# MX-64 310, MX-106 320; the DYNAMIXEL SDK's model lists agree). Stall torque and no-load speed
# are the servo catalog's (configs/servos/catalog.toml), not these tables'.
TABLES_1: Mapping[str, "ControlTable"] = MappingProxyType({t.model: t for t in (
    _table("AX-12A", 12, family="ax", defaults={"baud_rate": 1},
           source=_EMANUAL + "ax/ax-12a/#control-table"),
    _table("AX-18A", 18, family="ax", defaults={"baud_rate": 1},
           source=_EMANUAL + "ax/ax-18a/#control-table"),
    _table("RX-28", 28, family="ax", defaults={"max_voltage_limit": 190, "temperature_limit": 80},
           source=_EMANUAL + "rx/rx-28/#control-table"),
    _table("RX-64", 64, family="ax", defaults={"max_voltage_limit": 190, "temperature_limit": 80},
           source=_EMANUAL + "rx/rx-64/#control-table"),
    _table("MX-28(1.0)", 29, family="mx", defaults={},
           source=_EMANUAL + "mx/mx-28/#control-table"),
    _table("MX-64(1.0)", 310, family="mx", defaults={}, current=True,
           source=_EMANUAL + "mx/mx-64/#control-table"),
    _table("MX-106(1.0)", 320, family="mx", defaults={}, current=True,
           source=_EMANUAL + "mx/mx-106/#control-table"),
)})
# On a Protocol 1.0 bus the MX names mean the 1.0 firmware; "AX-12" (the older name) is the AX-12A.
ALIASES_1: Mapping[str, str] = MappingProxyType({
    "MX-28": "MX-28(1.0)", "MX-64": "MX-64(1.0)", "MX-106": "MX-106(1.0)", "AX-12": "AX-12A",
    "MX-28T": "MX-28(1.0)", "MX-28AT": "MX-28(1.0)", "MX-64T": "MX-64(1.0)", "MX-64AT": "MX-64(1.0)",
    "MX-106T": "MX-106(1.0)"})
