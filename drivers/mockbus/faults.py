"""Fault injection for the emulated bus.

A :class:`FaultInjector` is a controller object (mutable on purpose) that the emulator consults
for every reply. Tests script faults directly (``faults.silence(3)``) or at a time on the bus
clock (``faults.at(1.5, lambda bus: bus.faults.silence(3))``).

The same injector serves both buses, :class:`~drivers.mockbus.MockBus` (Protocol 2.0) and
:class:`~drivers.mockbus.MockBus1` (Protocol 1.0): the emulator mangles every status packet it
puts on the wire through :meth:`FaultInjector.mangle`, whatever its framing. On a 1.0 bus a
corrupted status fails its checksum, a lost or corrupted BULK_READ status leaves the servos
listed after it waiting (the rest of the list stays silent, as the firmware does), and the bits
of :meth:`FaultInjector.hardware_error` are the status error byte's alarm bits
(:class:`drivers.protocol1.ErrorBits1`: input voltage, overheating and overload have the 2.0
Hardware Error values). The reply faults draw from one RNG seeded with ``seed``; the counters
``dropped``, ``truncated`` and ``corrupted`` say how many statuses each fault took.
"""

from __future__ import annotations

import random
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from drivers.mockbus.emulator import MockBus

__all__ = ["FaultInjector", "ScheduledFault"]


@dataclass
class ScheduledFault:
    """An action run once when the bus clock passes ``at_s``."""

    at_s: float
    action: Callable[["MockBus"], None]
    done: bool = False


@dataclass
class FaultInjector:
    """Faults the emulator applies.

    Attributes:
        silent_ids: servos that never answer (as if unplugged); they still hear writes if
            ``deaf`` is False.
        deaf_ids: servos that ignore every packet (no writes applied either).
        stuck_ids: servos whose shaft is blocked (an obstacle, a jammed gear): they answer, but
            the shaft does not move (the plant, e.g. the physics twin, holds the joint where it
            was blocked) and the motor pushes toward its goal (up to stall torque, heating up).
        drop_probability: chance that a status packet is not sent.
        corrupt_probability: chance that one byte of a status packet is flipped.
        truncate_probability: chance that a status packet is cut short.
        extra_latency_s: added to every reply [s].
        input_voltage_v: supply voltage every servo sees [V] (per-ID override in
            ``voltage_by_id``).
        heating_gain: multiplies the emulator's I^2 heating (temperature rise under load).
        seed: seed of the fault RNG (reproducible).
        dropped / truncated / corrupted: status packets the reply faults have dropped, cut
            short and corrupted so far (what a benchmark compares with what the host noticed).
    """

    silent_ids: set[int] = field(default_factory=set)
    deaf_ids: set[int] = field(default_factory=set)
    stuck_ids: set[int] = field(default_factory=set)
    drop_probability: float = 0.0
    corrupt_probability: float = 0.0
    truncate_probability: float = 0.0
    extra_latency_s: float = 0.0
    input_voltage_v: float = 12.0
    voltage_by_id: dict[int, float] = field(default_factory=dict)
    heating_gain: float = 1.0
    pending_hardware_errors: dict[int, int] = field(default_factory=dict)
    scheduled: list[ScheduledFault] = field(default_factory=list)
    seed: int = 0
    dropped: int = 0
    truncated: int = 0
    corrupted: int = 0

    def __post_init__(self) -> None:
        self._rng = random.Random(self.seed)

    # ---- scripting helpers -----------------------------------------------------------
    def silence(self, servo_id: int) -> None:
        self.silent_ids.add(servo_id)

    def restore(self, servo_id: int) -> None:
        self.silent_ids.discard(servo_id)
        self.deaf_ids.discard(servo_id)
        self.stuck_ids.discard(servo_id)

    def block(self, servo_id: int) -> None:
        """Block the shaft of ``servo_id`` where it is (see ``stuck_ids``)."""
        self.stuck_ids.add(servo_id)

    def hardware_error(self, servo_id: int, bits: int) -> None:
        """Raise hardware error ``bits`` on ``servo_id`` at the next step (``HardwareErrorBits`` on
        2.0; on 1.0 the alarm bits of ``ErrorBits1``, e.g. ``ErrorBits1.OVERLOAD``)."""
        self.pending_hardware_errors[servo_id] = self.pending_hardware_errors.get(servo_id, 0) | bits

    def at(self, at_s: float, action: Callable[["MockBus"], None]) -> None:
        """Run ``action(bus)`` once the bus clock reaches ``at_s`` [s]."""
        self.scheduled.append(ScheduledFault(at_s, action))

    def voltage_of(self, servo_id: int) -> float:
        return self.voltage_by_id.get(servo_id, self.input_voltage_v)

    # ---- used by the emulator ----------------------------------------------------------
    def due(self, now_s: float) -> list[ScheduledFault]:
        out = [f for f in self.scheduled if not f.done and f.at_s <= now_s]
        for f in out:
            f.done = True
        return out

    def mangle(self, reply: bytes) -> bytes | None:
        """Apply the random reply faults; ``None`` means the reply is dropped."""
        rng = self._rng
        if self.drop_probability and rng.random() < self.drop_probability:
            self.dropped += 1
            return None
        if self.truncate_probability and rng.random() < self.truncate_probability:
            self.truncated += 1
            return reply[: rng.randrange(0, len(reply))]
        if self.corrupt_probability and rng.random() < self.corrupt_probability:
            self.corrupted += 1
            k = rng.randrange(len(reply))
            b = bytearray(reply)
            b[k] ^= 1 << rng.randrange(8)
            return bytes(b)
        return reply
