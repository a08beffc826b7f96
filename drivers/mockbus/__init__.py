"""Byte-level emulator of a Dynamixel Protocol 2.0 bus of X-series servos, and of a Protocol 1.0
bus of AX, RX and MX (1.0 firmware) servos (:class:`MockBus1`).

Importing this package registers the pyserial URL handler ``dxlsim://`` (see
:mod:`drivers.mockbus.protocol_dxlsim`), so ``serial.serial_for_url("dxlsim://NAME")`` works.
:mod:`drivers.mockbus.pty_server` serves a bus on a pseudo-terminal for any program
(``robot-rise mockbus serve``); a physics twin (``robot_rise.twin.MujocoTwin``) plugs in as the
:class:`Plant`.
"""

from __future__ import annotations

import serial

from drivers.mockbus.emulator import BAUD_BY_INDEX, MockBus, Reply
from drivers.mockbus.emulator1 import MockBus1
from drivers.mockbus.faults import FaultInjector, ScheduledFault
from drivers.mockbus.plant import JointPlant, KinematicPlant, Plant, ServoCommand, ServoFramePlant, ServoMotion
from drivers.mockbus.protocol_dxlsim import attach, attached, detach, parse_ids
from drivers.mockbus.pty_server import PtyServer, PtyServerProcess, spawn_pty_server
from drivers.mockbus.emulated_servo import EmulatedServo, ThermalModel
from drivers.mockbus.emulated_servo1 import EmulatedServo1

__all__ = [
    "BAUD_BY_INDEX",
    "MockBus",
    "MockBus1",
    "Reply",
    "FaultInjector",
    "ScheduledFault",
    "Plant",
    "JointPlant",
    "ServoFramePlant",
    "KinematicPlant",
    "ServoCommand",
    "ServoMotion",
    "EmulatedServo",
    "EmulatedServo1",
    "ThermalModel",
    "attach",
    "attached",
    "detach",
    "parse_ids",
    "PtyServer",
    "PtyServerProcess",
    "spawn_pty_server",
    "URL_SCHEME",
]

URL_SCHEME = "dxlsim"

if "drivers.mockbus" not in serial.protocol_handler_packages:
    serial.protocol_handler_packages.append("drivers.mockbus")
