"""Where the shipped configuration lives (robots, scenes, motion library).

The ``configs/`` directory sits beside the packages in the source tree. ``ROBOT_RISE_CONFIGS``
overrides it, e.g. for an installed copy that keeps its configs elsewhere.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["configs_dir", "default_robot_dir", "scene_path", "DEFAULT_ROBOT"]

DEFAULT_ROBOT = "op3"


def configs_dir() -> Path:
    """Return the configs directory (``$ROBOT_RISE_CONFIGS`` or ``<source tree>/configs``)."""
    env = os.environ.get("ROBOT_RISE_CONFIGS")
    if env:
        return Path(env)
    return Path(__file__).resolve().parent.parent / "configs"


def default_robot_dir() -> Path:
    """Return the directory of the embedded default robot."""
    return configs_dir() / "robots" / DEFAULT_ROBOT


def scene_path(name_or_path: str | os.PathLike[str]) -> Path:
    """Resolve a scene given as a file path or as a shipped scene name (``flat``, ``table`` ...)."""
    p = Path(name_or_path)
    if p.suffix == ".xml" or p.exists():
        return p
    return configs_dir() / "scenes" / f"{p.name}.xml"
