"""Where the shipped configuration lives (robots, scenes, servo catalog, motion library).

The ``configs/`` directory sits beside the packages in the source tree (a checkout or an editable
install uses it); a wheel ships the same files as package data, ``robot_rise/configs``, beside
this package in site-packages. ``ROBOT_RISE_CONFIGS`` overrides both. Found from this package's
own place, so ``drivers`` reaches the servo catalog without importing ``robot_rise``.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["configs_dir", "CONFIGS_ENV"]

CONFIGS_ENV = "ROBOT_RISE_CONFIGS"  # a configs directory to use instead of the shipped one


def configs_dir() -> Path:
    """Return the configs directory.

    In order: ``$ROBOT_RISE_CONFIGS``; ``<source tree>/configs`` (checkout, editable install);
    the package data ``robot_rise/configs`` of an installed wheel.
    """
    env = os.environ.get(CONFIGS_ENV)
    if env:
        return Path(env)
    root = Path(__file__).resolve().parent.parent
    # pyproject.toml marks a source tree: an installed copy's parent is site-packages, where some
    # other distribution may own a top-level "configs".
    if (root / "configs").is_dir() and (root / "pyproject.toml").is_file():
        return root / "configs"
    # The wheel installs robot_rise (with its configs) and this package side by side, unzipped:
    # callers need a real directory (MuJoCo reads the XML by path).
    return root / "robot_rise" / "configs"
