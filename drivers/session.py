"""Connecting to a servo bus in one call: a real port, or an emulated bus from the servo map.

The servo map's ``[bus] protocol`` picks the driver: :class:`~drivers.bus.DynamixelBus` and
:class:`~drivers.group.ServoGroup` for 2.0, :class:`~drivers.bus1.DynamixelBus1` and
:class:`~drivers.group1.ServoGroup1` for 1.0 (and :class:`~drivers.mockbus.MockBus1` emulates it).
"""

from __future__ import annotations

import itertools
import logging
import os
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

from drivers.bus import DynamixelBus
from drivers.bus1 import DynamixelBus1
from drivers.clock import Clock, MonotonicClock
from drivers.group import ServoGroup
from drivers.group1 import ServoGroup1
from drivers.port import LatencyTimer, ensure_low_latency, open_port, request_low_latency
from drivers.servo_map import ServoMap

__all__ = ["Connection", "connect", "mock_bus_for", "mock_url_for"]

if TYPE_CHECKING:
    from drivers.mockbus import FaultInjector, JointPlant, MockBus, Plant
    from drivers.mockbus.emulated_imu import EmulatedImu

_log = logging.getLogger(__name__)
_counter = itertools.count()
_RX_MARGIN_S = 0.004  # [s] reply timeout slack on a USB adapter (latency timer 1 ms + firmware)
_PTY_RX_MARGIN_S = 0.02  # [s] on a pseudo-terminal: the emulator process may be scheduled late


@dataclass
class Connection:
    """An open bus with its servo group (close it, or use it as a context manager)."""

    group: ServoGroup | ServoGroup1
    url: str
    latency: LatencyTimer

    @property
    def bus(self) -> DynamixelBus:
        return self.group.bus

    def close(self) -> None:
        self.group.bus.close()

    def __enter__(self) -> "Connection":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def mock_bus_for(servo_map: ServoMap, *, initial_rad: Mapping[str, float] | None = None,
                 wire_timing: bool = True, clock: Clock | None = None, return_delay_units: int = 0,
                 plant: "Plant | JointPlant | None" = None, imu: "EmulatedImu | None" = None,
                 faults: "FaultInjector | None" = None) -> "MockBus":
    """An emulated bus holding the servos of ``servo_map`` (at the map's baud rate).

    Args:
        initial_rad: starting joint angles by joint name [rad] (others start at 0, clamped to
            the map's limits).
        wire_timing: replies take their wire time at the map's baud rate.
        clock: the bus clock (default: real time).
        return_delay_units: Return Delay Time of every servo (2 us units).
        plant: what moves the shafts (default: the kinematic servo model): a
            :class:`drivers.mockbus.Plant` in the servo frame, or a
            :class:`drivers.mockbus.JointPlant` (the physics twin), put on the bus through this
            map (:class:`drivers.mockbus.ServoFramePlant`).
        imu: an OpenCR sub-controller on the bus (e.g. ``EmulatedImu()`` at ID 200), fed by the
            plant's IMU hook (the physics twin) unless it has a source of its own; None: no IMU.
        faults: the bus's fault injector (e.g. seeded); default: none, every servo at the map's
            supply voltage.
    """
    import drivers.mockbus as mb

    if plant is not None and not isinstance(plant, mb.Plant) and isinstance(plant, mb.JointPlant):
        plant = mb.ServoFramePlant(plant, servo_map)
    init = {}
    for s in servo_map.servos:
        q = (initial_rad or {}).get(s.joint, 0.0)
        init[s.id] = s.to_ticks(min(max(q, s.min), s.max))
    if faults is None:
        faults = mb.FaultInjector(input_voltage_v=servo_map.bus.supply_voltage_v)
    if servo_map.protocol == 1.0:
        if imu is not None:
            raise ValueError("the OpenCR (IMU) speaks Protocol 2.0; a Protocol 1.0 bus has none")
        return mb.MockBus1({s.id: s.model for s in servo_map.servos}, baud_rate=servo_map.bus.baud_rate,
                           faults=faults, clock=clock or MonotonicClock(), wire_timing=wire_timing, plant=plant,
                           initial_position_ticks=init, return_delay_units=return_delay_units)
    return mb.MockBus({s.id: s.model for s in servo_map.servos}, baud_rate=servo_map.bus.baud_rate,
                      faults=faults, clock=clock or MonotonicClock(), wire_timing=wire_timing, plant=plant,
                      initial_position_ticks=init, return_delay_units=return_delay_units, imu=imu)


def mock_url_for(servo_map: ServoMap, *, initial_rad: Mapping[str, float] | None = None,
                 wire_timing: bool = True, clock: Clock | None = None, return_delay_units: int = 0,
                 plant: "Plant | JointPlant | None" = None, imu: "EmulatedImu | None" = None) -> str:
    """Attach an emulated bus (see :func:`mock_bus_for`) and return its ``dxlsim://`` URL."""
    import drivers.mockbus as mb

    bus = mock_bus_for(servo_map, initial_rad=initial_rad, wire_timing=wire_timing, clock=clock,
                       return_delay_units=return_delay_units, plant=plant, imu=imu)
    return mb.attach(f"{servo_map.robot or 'bus'}{next(_counter)}", bus)


def connect(servo_map: ServoMap, port: str, *, baud_rate: int | None = None,
            clock: Clock | None = None, rx_margin_s: float | None = None) -> Connection:
    """Open ``port`` (device path or pyserial URL) for ``servo_map``'s servos.

    The adapter's latency timer is lowered where possible (FTDI), and reported otherwise.

    Args:
        rx_margin_s: slack on every reply timeout [s]; default 4 ms, or 20 ms on a
            pseudo-terminal, whose other end is a program sharing the CPU (the emulator).
    """
    baud = baud_rate or servo_map.bus.baud_rate
    latency = ensure_low_latency(port)
    _log.info("%s: %s", port, latency.note)
    if clock is None and port.startswith("dxlsim://"):
        import drivers.mockbus as mb

        emu = mb.attached(port.removeprefix("dxlsim://"))
        clock = emu.clock if emu is not None else None
    clock = clock or MonotonicClock()
    serial_port = open_port(port, baud)
    if "://" not in port:
        latency = replace(latency, note=f"{latency.note}; {request_low_latency(serial_port)}")
    if rx_margin_s is None:
        rx_margin_s = _PTY_RX_MARGIN_S if os.path.realpath(port).startswith("/dev/pts/") else _RX_MARGIN_S
    return_delay_s = servo_map.bus.return_delay_time_us * 1e-6 + 50e-6
    if servo_map.protocol == 1.0:
        bus1 = DynamixelBus1(serial_port, baud_rate=baud, clock=clock, rx_margin_s=rx_margin_s,
                             return_delay_s=return_delay_s)
        return Connection(ServoGroup1(bus1, servo_map), port, latency)
    bus = DynamixelBus(serial_port, baud_rate=baud, clock=clock, rx_margin_s=rx_margin_s,
                       return_delay_s=return_delay_s)
    return Connection(ServoGroup(bus, servo_map), port, latency)
