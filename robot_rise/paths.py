"""Where the shipped configuration lives (robots, scenes, motion library).

The ``configs/`` directory sits beside the packages in the source tree (a checkout or an editable
install uses it); a wheel ships the same files as package data, ``robot_rise/configs``.
``ROBOT_RISE_CONFIGS`` overrides both. :func:`configs_dir` is :mod:`robot_files.paths`' (``drivers``
finds the servo catalog there too).
"""

from __future__ import annotations

import os
from pathlib import Path

from robot_files.paths import configs_dir

__all__ = ["configs_dir", "default_robot_dir", "scene_path", "DEFAULT_ROBOT"]

DEFAULT_ROBOT = "op3"


def default_robot_dir() -> Path:
    """Return the directory of the embedded default robot."""
    return configs_dir() / "robots" / DEFAULT_ROBOT


def scene_path(name_or_path: str | os.PathLike[str]) -> Path:
    """Resolve a scene given as a file path or as a shipped scene name (``flat``, ``table`` ...)."""
    p = Path(name_or_path)
    if p.suffix == ".xml" or p.exists():
        return p
    return configs_dir() / "scenes" / f"{p.name}.xml"
