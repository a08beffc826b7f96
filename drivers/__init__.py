"""drivers: Dynamixel Protocol 2.0 side of robot_rise (bytes and ticks live only here).

Layers: :mod:`~drivers.protocol` (packets, CRC) -> :mod:`~drivers.bus` (transactions) ->
:mod:`~drivers.group` (a servo map's cycle I/O in radians) -> :mod:`~drivers.startup`
(preflight, engage, recovery) and :mod:`~drivers.executor` (fixed-rate streaming under
:mod:`~drivers.safety`). :mod:`~drivers.mockbus` emulates the servos byte for byte.
This package never imports ``robot_rise``.
"""

from drivers.bus import DynamixelBus, GroupRead, PingResult
from drivers.clock import Clock, FakeClock, MonotonicClock
from drivers.control_table import SUPPORTED_MODELS, ControlTable, HardwareErrorBits, control_table
from drivers.errors import (
    CommunicationError,
    DriverError,
    PreflightError,
    ProtocolError,
    SafetyError,
    ServoMapError,
    ServoTimeout,
)
from drivers.executor import ExecutionReport, Executor, ExecutorConfig
from drivers.group import Feedback, ServoGroup
from drivers.port import open_port
from drivers.safety import SafetyLimits, StopPolicy, voltage_limits_for_supply
from drivers.servo_map import ServoMap, ServoSpec, load_servo_map
from drivers.startup import PreflightReport, engage, preflight, recover

__all__ = [
    "DynamixelBus",
    "GroupRead",
    "PingResult",
    "Clock",
    "FakeClock",
    "MonotonicClock",
    "SUPPORTED_MODELS",
    "ControlTable",
    "HardwareErrorBits",
    "control_table",
    "CommunicationError",
    "DriverError",
    "PreflightError",
    "ProtocolError",
    "SafetyError",
    "ServoMapError",
    "ServoTimeout",
    "ExecutionReport",
    "Executor",
    "ExecutorConfig",
    "Feedback",
    "ServoGroup",
    "open_port",
    "SafetyLimits",
    "voltage_limits_for_supply",
    "StopPolicy",
    "ServoMap",
    "ServoSpec",
    "load_servo_map",
    "PreflightReport",
    "engage",
    "preflight",
    "recover",
]
