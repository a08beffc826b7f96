"""Time sources: a :class:`Clock` protocol, the real monotonic clock and a fake clock for tests.

The executor, the bus timeouts and the emulator all read time through a ``Clock`` so that timing
logic can be tested deterministically: with :class:`FakeClock`, ``sleep`` just advances time.
"""

from __future__ import annotations

import time
from typing import Protocol, runtime_checkable

__all__ = ["Clock", "MonotonicClock", "FakeClock"]

_SPIN_S = 0.0003  # [s] final stretch of a precise sleep that is busy-waited


@runtime_checkable
class Clock(Protocol):
    """A monotonic time source in [s]."""

    def now(self) -> float:
        """Current time [s] (arbitrary origin, monotonic)."""
        ...

    def sleep(self, duration_s: float) -> None:
        """Wait ``duration_s`` [s] (no-op if <= 0)."""
        ...


class MonotonicClock:
    """Real time via ``time.perf_counter``; ``sleep`` is precise to ~50 us.

    Args:
        spin_s: the last part of every sleep is busy-waited for precision [s]; 0 disables it.
    """

    def __init__(self, *, spin_s: float = _SPIN_S) -> None:
        self._spin_s = spin_s

    def now(self) -> float:
        return time.perf_counter()

    def sleep(self, duration_s: float) -> None:
        if duration_s <= 0:
            return
        end = time.perf_counter() + duration_s
        coarse = duration_s - self._spin_s
        if coarse > 0:
            time.sleep(coarse)
        while time.perf_counter() < end:
            pass


class FakeClock:
    """Deterministic clock for tests: ``sleep`` advances time instantly.

    Args:
        start_s: initial time [s].
    """

    def __init__(self, start_s: float = 0.0) -> None:
        self._t = float(start_s)

    def now(self) -> float:
        return self._t

    def sleep(self, duration_s: float) -> None:
        if duration_s > 0:
            self._t += duration_s

    def advance(self, duration_s: float) -> None:
        """Move time forward by ``duration_s`` [s]."""
        self.sleep(duration_s)
