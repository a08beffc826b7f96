"""Opening a serial port (real adapter, pseudo-terminal or ``dxlsim://`` emulator) and the
USB adapter's latency timer.

FTDI adapters (U2D2: USB id 0403:6014) buffer replies for their latency timer (default 16 ms),
which caps any loop near 60 Hz; Linux exposes it at
``/sys/bus/usb-serial/devices/ttyUSBx/latency_timer``. We set it to 1 ms when we can and
degrade gracefully (a warning with a hint) when the file is absent (pseudo-terminal, CDC-ACM
adapters) or not writable.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path

import serial

from drivers.errors import CommunicationError

__all__ = ["LatencyTimer", "open_port", "latency_timer_path", "ensure_low_latency", "request_low_latency"]

_log = logging.getLogger(__name__)
_SYSFS = Path("/sys/bus/usb-serial/devices")
TARGET_LATENCY_MS = 1


@dataclass(frozen=True)
class LatencyTimer:
    """Outcome of the latency-timer check.

    Attributes:
        path: sysfs file, or ``None`` when the adapter has none.
        before_ms: value found [ms] (``None`` if unknown).
        after_ms: value after our attempt [ms] (``None`` if unknown).
        note: one line for the operator.
    """

    path: Path | None
    before_ms: int | None
    after_ms: int | None
    note: str


def latency_timer_path(device: str, sysfs: Path = _SYSFS) -> Path | None:
    """The sysfs latency-timer file of ``device`` (e.g. ``/dev/ttyUSB0``), if it exists."""
    try:
        name = Path(os.path.realpath(device)).name
    except OSError:
        return None
    path = sysfs / name / "latency_timer"
    return path if path.exists() else None


def ensure_low_latency(device: str, *, sysfs: Path = _SYSFS, target_ms: int = TARGET_LATENCY_MS) -> LatencyTimer:
    """Check the latency timer of ``device`` and lower it to ``target_ms`` if possible."""
    if "://" in device:
        return LatencyTimer(None, None, None, "emulated port: no latency timer")
    path = latency_timer_path(device, sysfs)
    if path is None:
        return LatencyTimer(None, None, None, "no latency timer for this adapter (not FTDI or a pseudo-terminal)")
    try:
        before = int(path.read_text().strip())
    except (OSError, ValueError) as e:
        return LatencyTimer(path, None, None, f"cannot read {path}: {e}")
    if before <= target_ms:
        return LatencyTimer(path, before, before, f"latency timer {before} ms")
    try:
        path.write_text(f"{target_ms}\n")
        after = int(path.read_text().strip())
    except (OSError, ValueError) as e:
        _log.warning("latency timer of %s is %d ms and could not be lowered: %s", device, before, e)
        return LatencyTimer(path, before, before,
                            f"latency timer {before} ms (caps the loop near {1000 // (2 * before)} Hz); "
                            f"add a udev rule setting it to 1 or run: echo 1 | sudo tee {path}")
    return LatencyTimer(path, before, after, f"latency timer lowered {before} -> {after} ms")


def open_port(url: str, baud_rate: int, *, timeout_s: float = 0.01) -> serial.SerialBase:
    """Open ``url`` (device path, ``dxlsim://NAME`` or any pyserial URL) at ``baud_rate`` [bit/s].

    Raises:
        CommunicationError: the port cannot be opened.
    """
    if url.startswith("dxlsim://"):
        import drivers.mockbus  # noqa: F401  (registers the URL handler)
    try:
        port = serial.serial_for_url(url, baudrate=baud_rate, timeout=timeout_s, write_timeout=1.0)
    except (serial.SerialException, OSError, ValueError) as e:
        raise CommunicationError(
            f"cannot open port {url!r} at {baud_rate} bit/s: {e}",
            hint="check the device path (ls /dev/ttyUSB*), permissions (dialout group) and that "
                 "no other program holds the port",
        ) from e
    return port


def request_low_latency(port: object) -> str:
    """Ask the serial driver for its low-latency mode (``ASYNC_LOW_LATENCY`` ioctl); returns a note.

    Pseudo-terminals, the ``dxlsim://`` emulator and many USB adapters reject the ioctl; that is
    reported, not raised (the latency timer matters more on FTDI adapters).
    """
    setter = getattr(port, "set_low_latency_mode", None)
    if setter is None:
        return "low-latency mode not available on this port type"
    try:
        setter(True)
    except (OSError, ValueError, NotImplementedError) as e:
        _log.debug("low-latency ioctl rejected: %s", e)
        return "low-latency ioctl not supported (pseudo-terminal or non-FTDI adapter)"
    return "low-latency mode on"
