"""Byte-level emulator of a Dynamixel Protocol 2.0 bus of X-series servos.

Importing this package registers the pyserial URL handler ``dxlsim://`` (see
:mod:`drivers.mockbus.protocol_dxlsim`), so ``serial.serial_for_url("dxlsim://NAME")`` works.
"""

from __future__ import annotations

import serial

from drivers.mockbus.bus import BAUD_BY_INDEX, MockBus, Reply
from drivers.mockbus.faults import FaultInjector, ScheduledFault
from drivers.mockbus.plant import KinematicPlant, Plant, ServoCommand, ServoMotion
from drivers.mockbus.protocol_dxlsim import attach, attached, detach, parse_ids
from drivers.mockbus.servo import EmulatedServo, ThermalModel

__all__ = [
    "BAUD_BY_INDEX",
    "MockBus",
    "Reply",
    "FaultInjector",
    "ScheduledFault",
    "Plant",
    "KinematicPlant",
    "ServoCommand",
    "ServoMotion",
    "EmulatedServo",
    "ThermalModel",
    "attach",
    "attached",
    "detach",
    "parse_ids",
    "URL_SCHEME",
]

URL_SCHEME = "dxlsim"

if "drivers.mockbus" not in serial.protocol_handler_packages:
    serial.protocol_handler_packages.append("drivers.mockbus")
