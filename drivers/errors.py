"""Errors raised by ``drivers`` on purpose.

Rule: dynamixel-sdk, pyserial and OS errors are re-raised as these (``raise ... from e``) so the
caller never has to know which library sits underneath. Every error may carry a one-line
``hint`` telling the operator what to do about it.
"""

from __future__ import annotations

from collections.abc import Sequence

from robot_files.errors import HintedError

__all__ = [
    "DriverError",
    "ServoMapError",
    "ControlTableError",
    "ProtocolError",
    "CommunicationError",
    "ServoTimeout",
    "ServoStatusError",
    "PreflightError",
    "SafetyError",
]


class DriverError(HintedError):
    """Root of every error ``drivers`` raises on purpose.

    Attributes:
        hint: one line telling the operator what to do about it (may be empty).
    """


class ServoMapError(DriverError):
    """The servo map TOML is missing, malformed or inconsistent."""


class ControlTableError(DriverError):
    """Unknown servo model or register name."""


class ProtocolError(DriverError):
    """A byte sequence is not a valid Protocol 2.0 packet (header, length, CRC)."""


class CommunicationError(DriverError):
    """The bus could not complete a transaction (port failure, no or corrupt reply)."""


class ServoTimeout(CommunicationError):
    """One or more servos did not answer.

    Attributes:
        ids: the silent servo IDs.
        packet: the instruction packet that went unanswered (may be empty).
    """

    def __init__(self, ids: Sequence[int], packet: bytes = b"", *, hint: str = "") -> None:
        self.ids = tuple(ids)
        self.packet = bytes(packet)
        super().__init__(
            f"no reply from servo id(s) {list(self.ids)}",
            hint=hint or "check power, cabling, baud rate and IDs (robot-rise servos scan)",
        )


class ServoStatusError(CommunicationError):
    """A servo answered with a non-zero error number in its status packet.

    Attributes:
        servo_id: the servo.
        error: the raw error byte (bit 7 is the hardware alert bit).
    """

    def __init__(self, servo_id: int, error: int, what: str, *, hint: str = "") -> None:
        self.servo_id = servo_id
        self.error = error
        super().__init__(f"servo {servo_id}: {what} (status error byte 0x{error:02X})", hint=hint)


class PreflightError(DriverError):
    """Start-up checks failed (missing servo, wrong model, settings that cannot be applied)."""


class SafetyError(DriverError):
    """A request was refused by the safety layer (e.g. start far from the present posture)."""
