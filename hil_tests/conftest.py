"""Shared fixtures: an emulated OP3 bus on a fake clock, and the real bus when
``ROBOT_RISE_PORT`` is set (tests marked ``hardware`` are skipped otherwise)."""

from __future__ import annotations

import contextlib
import itertools
import os
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

import drivers.mockbus as mb
from drivers.bus import DynamixelBus
from drivers.clock import FakeClock
from drivers.group import ServoGroup
from drivers.mockbus.pty_server import PtyServer
from drivers.port import open_port
from drivers.safety import SafetyLimits
from drivers.servo_map import ServoMap, load_servo_map

REPO = Path(__file__).resolve().parents[1]
SERVO_MAP = REPO / "configs" / "robots" / "op3" / "servos.toml"
_names = itertools.count()


_HARDWARE_SKIP = "needs a real Dynamixel bus: set ROBOT_RISE_PORT=/dev/ttyUSB0"
_skipped_hardware: list[str] = []


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "motion: engages torque on a real bus (also needs ROBOT_RISE_ALLOW_MOTION=1)")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if os.environ.get("ROBOT_RISE_PORT"):
        return
    skip = pytest.mark.skip(reason=_HARDWARE_SKIP)
    for item in items:
        if "hardware" in item.keywords:
            item.add_marker(skip)
            _skipped_hardware.append(item.nodeid)


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    """Say why the real-bus variants did not run (pytest alone prints only an ``s``)."""
    if _skipped_hardware:
        terminalreporter.write_line(
            f"hil_tests: {len(_skipped_hardware)} real-bus test(s) skipped ({_HARDWARE_SKIP}); "
            "their emulator variants ran")


@pytest.fixture(scope="session")
def servo_map() -> ServoMap:
    return load_servo_map(SERVO_MAP)


@dataclass
class Rig:
    """An emulated bus and the host objects talking to it."""

    clock: FakeClock
    mock: mb.MockBus
    bus: DynamixelBus
    group: ServoGroup
    servo_map: ServoMap
    url: str

    def limits(self, **kw: float) -> SafetyLimits:
        return SafetyLimits(self.servo_map.lower_rad, self.servo_map.upper_rad, **kw)


def make_rig(servo_map: ServoMap, *, initial_rad: np.ndarray | None = None, **bus_kwargs: object) -> Rig:
    clock = FakeClock(100.0)
    init = None
    if initial_rad is not None:
        ticks = servo_map.to_ticks(initial_rad)
        init = {s.id: int(t) for s, t in zip(servo_map.servos, ticks)}
    mock = mb.MockBus({s.id: s.model for s in servo_map.servos}, baud_rate=servo_map.bus.baud_rate,
                      clock=clock, initial_position_ticks=init, **bus_kwargs)  # type: ignore[arg-type]
    name = f"rig{next(_names)}"
    url = mb.attach(name, mock)
    bus = DynamixelBus(open_port(url, servo_map.bus.baud_rate), baud_rate=servo_map.bus.baud_rate, clock=clock)
    return Rig(clock, mock, bus, ServoGroup(bus, servo_map), servo_map, url)


@pytest.fixture
def rig(servo_map: ServoMap) -> Rig:
    return make_rig(servo_map)


@contextlib.contextmanager
def pty_served_by_thread(bus: mb.MockBus) -> Iterator[PtyServer]:
    """``bus`` on a pseudo-terminal served by a thread of this process, stopped and closed on exit."""
    server = PtyServer(bus)
    server.open()
    thread = threading.Thread(target=server.serve, daemon=True)
    thread.start()
    try:
        yield server
    finally:
        server.stop()
        thread.join(5.0)
        server.close()


@pytest.fixture
def hardware_port() -> str:
    port = os.environ.get("ROBOT_RISE_PORT")
    if not port:
        pytest.skip("needs a real Dynamixel bus: set ROBOT_RISE_PORT")
    return port
