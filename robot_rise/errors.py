"""The one root exception of robot_rise and its per-area subclasses.

Library code raises these (wrapping third-party errors with ``raise ... from e``) so the CLI can
print one clear line plus a hint. An expected planning or filtering failure is a status in a
result object, not an exception.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from robot_files.errors import HintedError, RobotFileError

__all__ = [
    "RobotRiseError",
    "ConfigError",
    "FormatError",
    "PostureError",
    "SceneError",
    "as_config_error",
    "mujoco_reason",
]


class RobotRiseError(HintedError):
    """Root of every error robot_rise raises on purpose.

    Attributes:
        hint: one line telling the user what to do about it (may be empty).
    """


class ConfigError(RobotRiseError):
    """A robot directory, servo map or scene is missing or malformed."""


class FormatError(RobotRiseError):
    """A file does not follow its declared ``format`` (wrong version, missing field, bad value)."""


class PostureError(FormatError):
    """A posture is malformed or does not fit the robot (unknown joint, limit, quaternion)."""


class SceneError(ConfigError):
    """A scene file cannot be composed with the robot."""


@contextmanager
def as_config_error() -> Iterator[None]:
    """Re-raise a :class:`robot_files.errors.RobotFileError` (servo map, servo catalog, TOML) as
    :class:`ConfigError`, message and hint unchanged."""
    try:
        yield
    except RobotFileError as e:
        raise ConfigError(str(e), hint=e.hint) from None


def mujoco_reason(error: BaseException) -> str:
    """MuJoCo's message as one line: its reason (the first line, which says why) and the element
    it names (its last lines say only where: "Element name 'x', id 13")."""
    lines = [line.strip() for line in str(error).strip().splitlines() if line.strip()]
    if not lines:
        return type(error).__name__
    reason = lines[0].removeprefix("Error: ").rstrip(".")
    element = next((line for line in lines[1:] if line.lower().startswith(("element", "object"))), "")
    return f"{reason} ({element})" if element and element not in reason else reason
