"""Where the shipped configuration lives (robots, scenes, motion library).

The ``configs/`` directory sits beside the packages in the source tree (a checkout or an editable
install uses it); a wheel ships the same files as package data, ``robot_rise/configs``.
``ROBOT_RISE_CONFIGS`` overrides both.
"""

from __future__ import annotations

import os
from importlib.resources import files
from pathlib import Path

__all__ = ["configs_dir", "default_robot_dir", "scene_path", "DEFAULT_ROBOT"]

DEFAULT_ROBOT = "op3"


def configs_dir() -> Path:
    """Return the configs directory.

    In order: ``$ROBOT_RISE_CONFIGS``; ``<source tree>/configs`` (checkout, editable install);
    the package data ``robot_rise/configs`` of an installed wheel.
    """
    env = os.environ.get("ROBOT_RISE_CONFIGS")
    if env:
        return Path(env)
    root = Path(__file__).resolve().parent.parent
    # pyproject.toml marks a source tree: an installed copy's parent is site-packages, where some
    # other distribution may own a top-level "configs".
    if (root / "configs").is_dir() and (root / "pyproject.toml").is_file():
        return root / "configs"
    # Callers need a real directory (MuJoCo reads the XML by path). Wheels install unzipped, so
    # the resource is one; a zipimported robot_rise is not supported.
    return Path(str(files("robot_rise") / "configs"))


def default_robot_dir() -> Path:
    """Return the directory of the embedded default robot."""
    return configs_dir() / "robots" / DEFAULT_ROBOT


def scene_path(name_or_path: str | os.PathLike[str]) -> Path:
    """Resolve a scene given as a file path or as a shipped scene name (``flat``, ``table`` ...)."""
    p = Path(name_or_path)
    if p.suffix == ".xml" or p.exists():
        return p
    return configs_dir() / "scenes" / f"{p.name}.xml"
