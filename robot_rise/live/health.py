"""The servos' health before a get-up: what is read, the limits, and the reasons not to move."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace

__all__ = ["Health", "HealthLimits", "health_limits_for_supply", "health_problems"]


@dataclass(frozen=True)
class Health:
    """The servos' state before a try.

    Attributes:
        temperatures_c: servo temperature by joint [degC].
        voltages_v: servo input voltage by joint [V].
        hardware_errors: a description of the hardware error by joint (only joints with one).
        missing: joints whose servo did not answer.
    """

    temperatures_c: Mapping[str, float] = field(default_factory=dict)
    voltages_v: Mapping[str, float] = field(default_factory=dict)
    hardware_errors: Mapping[str, str] = field(default_factory=dict)
    missing: tuple[str, ...] = ()


@dataclass(frozen=True)
class HealthLimits:
    """When not to try (ours). A get-up is 5-10 s of hard work: it must start with headroom below
    the executor's own abort thresholds (``drivers.safety.SafetyLimits``: 70 degC, 10.0 V).

    Attributes:
        max_temperature_c: [degC] a hotter servo refuses the try: the XM430's windings gain a
            few kelvin in a get-up; 65 keeps the executor's 70 degC abort out of reach.
        min_voltage_v: [V] below it the supply is nearly flat (a 3S LiPo at 3.5 V a cell); the
            servos lose torque the proof counted on (its weakest variant: the supply -7.5 %, 11.1 V of 12).
        max_voltage_v: [V] above the servos' recommended range.
    """

    max_temperature_c: float = 65.0
    min_voltage_v: float = 10.5
    max_voltage_v: float = 14.5


def health_limits_for_supply(supply_v: float) -> HealthLimits:
    """:class:`HealthLimits` for servos on ``supply_v`` (the servo map's ``[bus]
    supply_voltage_v``): the 12 V figures scaled (a 4S LiPo's 14.8 V: 12.95-17.9 V)."""
    k = supply_v / 12.0
    return replace(HealthLimits(), min_voltage_v=HealthLimits.min_voltage_v * k, max_voltage_v=HealthLimits.max_voltage_v * k)


def health_problems(health: Health, limits: HealthLimits = HealthLimits()) -> tuple[str, ...]:
    """One line per reason not to move (empty: healthy)."""
    out = [f"servo of {j} did not answer" for j in health.missing]
    out += [f"{j}: hardware error ({why})" for j, why in health.hardware_errors.items()]
    out += [f"{j}: {t:.0f} degC, above {limits.max_temperature_c:.0f} degC"
            for j, t in health.temperatures_c.items() if not t <= limits.max_temperature_c]
    out += [f"{j}: {v:.1f} V, outside {limits.min_voltage_v:.1f}..{limits.max_voltage_v:.1f} V"
            for j, v in health.voltages_v.items() if not limits.min_voltage_v <= v <= limits.max_voltage_v]
    return tuple(out)
