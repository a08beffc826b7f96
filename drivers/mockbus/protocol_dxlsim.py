"""pyserial URL handler ``dxlsim://NAME[?options]``: an in-process port onto a :class:`MockBus`.

``serial.serial_for_url("dxlsim://op3")`` opens the bus attached under ``op3`` with
:func:`drivers.mockbus.attach`; if none is attached, a bus is created from the options:

- ``ids=1-20`` (ranges and commas), ``model=XM430-W350``,
- ``baud=1000000`` (bus baud rate; the port's own baud must match to be understood),
- ``wire_timing=1`` (replies take their wire time), ``delay=0`` (Return Delay Time units),
- ``fake_clock=1`` (deterministic time; sleeping advances it),
- ``protocol=1.0`` (a Protocol 1.0 bus, :class:`~drivers.mockbus.MockBus1`; ``model`` then
  names a 1.0 model, default ``MX-28``).

Reads honour the port timeout on the bus clock: with a fake clock a timeout simply advances
time, so a silent servo costs no real time in tests.
"""

from __future__ import annotations

import time
import urllib.parse
from typing import Any

import serial

from drivers.mockbus.emulator import MockBus

__all__ = ["Serial", "attach", "detach", "attached", "parse_ids"]

_BUSES: dict[str, MockBus] = {}


def attach(name: str, bus: MockBus) -> str:
    """Make ``bus`` reachable as ``dxlsim://name``; returns the URL."""
    _BUSES[name] = bus
    return f"dxlsim://{name}"


def detach(name: str) -> None:
    _BUSES.pop(name, None)


def attached(name: str) -> MockBus | None:
    return _BUSES.get(name)


def parse_ids(text: str) -> list[int]:
    """``"1-3,7"`` -> ``[1, 2, 3, 7]``."""
    ids: list[int] = []
    for part in text.split(","):
        part = part.strip()
        if not part:
            continue
        if "-" in part:
            a, b = part.split("-", 1)
            ids.extend(range(int(a), int(b) + 1))
        else:
            ids.append(int(part))
    return ids


class Serial(serial.SerialBase):
    """A pyserial port whose other end is an emulated Dynamixel bus."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.bus: MockBus | None = None
        self._pending: list[tuple[float, bytes]] = []
        self.emulator_time_s = 0.0  # [s] thread CPU time spent inside the emulator
        self.bytes_written = 0
        self.bytes_read = 0
        super().__init__(*args, **kwargs)

    def open(self) -> None:
        if self._port is None:
            raise serial.SerialException("port must be configured before it can be used")
        if self.is_open:
            raise serial.SerialException("port already open")
        self.bus = self._bus_from_url(self._port)
        self.is_open = True
        self._pending = []

    def close(self) -> None:
        self.is_open = False
        self._pending = []

    def _reconfigure_port(self) -> None:
        pass

    def _bus_from_url(self, url: str) -> MockBus:
        parts = urllib.parse.urlsplit(url)
        if parts.scheme != "dxlsim":
            raise serial.SerialException(f"expected a dxlsim:// URL, not {url!r}")
        name = parts.netloc or parts.path.lstrip("/")
        bus = _BUSES.get(name)
        if bus is not None:
            return bus
        opts = dict(urllib.parse.parse_qsl(parts.query))
        try:
            from drivers.clock import FakeClock

            ids = parse_ids(opts.get("ids", "1"))
            one = float(opts.get("protocol", "2.0")) == 1.0
            if one:
                from drivers.mockbus.emulator1 import MockBus1
            bus = (MockBus1 if one else MockBus).from_ids(
                ids, opts.get("model", "MX-28" if one else "XM430-W350"),
                baud_rate=int(opts.get("baud", str(self._baudrate or 1_000_000))),
                wire_timing=opts.get("wire_timing", "0") == "1",
                return_delay_units=int(opts.get("delay", "0")),
                clock=FakeClock() if opts.get("fake_clock", "0") == "1" else None,
            )
        except (ValueError, KeyError) as e:
            raise serial.SerialException(f"bad dxlsim URL {url!r}: {e}") from e
        if name:
            _BUSES[name] = bus
        return bus

    # ---- data ----------------------------------------------------------------------------
    def _now(self) -> float:
        assert self.bus is not None
        return self.bus.clock.now()

    @property
    def in_waiting(self) -> int:
        now = self._now()
        return sum(len(d) for t, d in self._pending if t <= now)

    def write(self, data: bytes) -> int:
        if not self.is_open or self.bus is None:
            raise serial.PortNotOpenError()
        data = bytes(data)
        t0 = time.thread_time()
        if self._baudrate == self.bus.baud_rate:
            replies = self.bus.receive(data)
            self._pending.extend((r.ready_s, r.data) for r in replies)
        self.emulator_time_s += time.thread_time() - t0
        self.bytes_written += len(data)
        return len(data)

    def read(self, size: int = 1) -> bytes:
        if not self.is_open or self.bus is None:
            raise serial.PortNotOpenError()
        clock = self.bus.clock
        timeout = self._timeout
        now = clock.now()
        deadline = now + (timeout if timeout is not None else 3600.0)
        out = bytearray()
        while len(out) < size:
            now = clock.now()
            while self._pending and self._pending[0][0] <= now and len(out) < size:
                t, d = self._pending.pop(0)
                take = size - len(out)
                out += d[:take]
                if len(d) > take:
                    self._pending.insert(0, (t, d[take:]))
            if len(out) >= size:
                break
            if not self._pending:
                if timeout is None:
                    break  # nothing more will ever arrive on a half-duplex bus
                if deadline > now:
                    clock.sleep(deadline - now)
                break
            next_ready = self._pending[0][0]
            if next_ready > deadline:
                if deadline > now:
                    clock.sleep(deadline - now)
                break
            t0 = time.thread_time()
            clock.sleep(next_ready - now)
            self.emulator_time_s += time.thread_time() - t0
        self.bytes_read += len(out)
        return bytes(out)

    def reset_input_buffer(self) -> None:
        now = self._now()
        self._pending = [(t, d) for t, d in self._pending if t > now]

    def reset_output_buffer(self) -> None:
        pass

    @property
    def out_waiting(self) -> int:
        return 0

    def _update_break_state(self) -> None:
        pass

    def _update_rts_state(self) -> None:
        pass

    def _update_dtr_state(self) -> None:
        pass

    @property
    def cts(self) -> bool:
        return True

    @property
    def dsr(self) -> bool:
        return True

    @property
    def ri(self) -> bool:
        return False

    @property
    def cd(self) -> bool:
        return True
