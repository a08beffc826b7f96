"""The wall-clock deadline of the refinement steps (a ``time.monotonic()`` value, None: none).

Each refinement step (key postures, straightening, second stage, dense output) only ever replaces
a legal motion by another legal one, so once the deadline has passed it stops where it is.
"""

from __future__ import annotations

import time

__all__ = ["deadline_passed"]


def deadline_passed(deadline: float | None) -> bool:
    """Has the ``time.monotonic()`` deadline passed (None: no deadline)?"""
    return deadline is not None and time.monotonic() >= deadline
