"""The one error of the pictures room: rendering is impossible here or was asked wrongly."""

from __future__ import annotations

from robot_rise.errors import RobotRiseError

__all__ = ["RenderError"]


class RenderError(RobotRiseError):
    """Rendering is impossible here (no OpenGL backend, no encoder) or was asked wrongly."""
