"""The error of :mod:`robot_files`, and the base every root error of the project shares.

Rule: every message is one line that starts with the file it is about (where there is one) and
names the problem; ``hint`` says what to do. ``robot_rise`` re-raises it as its ``ConfigError``,
``drivers`` as its ``ServoMapError`` (``raise ... from None``), so neither side's callers have to
know this package sits underneath.
"""

from __future__ import annotations

__all__ = ["HintedError", "RobotFileError"]


class HintedError(Exception):
    """An error raised on purpose: a one-line message and what to do about it. The base of this
    package's, ``drivers``' (``DriverError``) and ``robot_rise``'s (``RobotRiseError``) roots.

    Attributes:
        hint: one line telling the user what to do about it (may be empty).
    """

    def __init__(self, message: str, *, hint: str = "") -> None:
        super().__init__(message)
        self.hint = hint


class RobotFileError(HintedError):
    """A robot file (servo map, servo catalog, any TOML file read here) is missing or malformed."""
