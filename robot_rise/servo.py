"""Dynamixel servo parameters per model (data) and the torque-speed envelope (pure functions).

A Dynamixel in position mode runs a P(ID) loop on the position error and drives its DC motor with
the resulting PWM duty u in [-1, 1] (885 = 100 %). A DC motor at duty u and speed w gives

    tau = tau_stall(V) * (u - w / w_noload(V))                                   (DC motor)

so the reachable torque at speed w lies in the envelope
    -tau_stall * (1 + w / w_noload) <= tau <= tau_stall * (1 - w / w_noload).

The position loop: u = clip(Kp_pwm * e_ticks / 885, -1, 1) with Kp_pwm = P / 128 (PWM units per
tick, e-manual). In SI, the torque per radian of error before saturation is

    kp_eff = (P / 128) * (4096 / 2 pi) * tau_stall / 885        [N m / rad]

For the XM430-W350 at 12 V with the default P = 800: 6.25 * 651.9 * 4.1 / 885 = 18.9 N m/rad,
and the duty saturates at 885 / 6.25 = 141.6 ticks = 0.217 rad of error. The back-EMF term is a
viscous torque with coefficient tau_stall / w_noload (independent of voltage, since both scale
with V). In MuJoCo this is exact with one position actuator (kp_eff, force range +-tau_stall)
plus joint damping tau_stall / w_noload: see robot_rise/model.py.

Sources: ROBOTIS e-manual performance tables and control tables (../shared/facts/dynamixel.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot_rise.errors import ConfigError

__all__ = [
    "ServoDatasheet",
    "SERVO_DATASHEETS",
    "servo_datasheet",
    "TICKS_PER_REV",
    "PWM_LIMIT",
    "torque_limits",
    "envelope_ratio",
    "position_mode_torque",
    "ServoArrays",
    "servo_arrays",
]

TICKS_PER_REV = 4096  # position resolution of X-series / MX(2.0) servos
PWM_LIMIT = 885  # PWM register value for 100 % duty


@dataclass(frozen=True)
class ServoDatasheet:
    """Performance of one servo model at its nominal voltage.

    Attributes:
        model: model name as ROBOTIS writes it.
        nominal_voltage_v: voltage of the datasheet figures [V].
        stall_torque_nm: stall torque at nominal voltage [N m].
        no_load_speed_rad_s: no-load speed at nominal voltage [rad/s].
        gear_ratio: gearbox reduction.
        position_p_gain: default Position P Gain register value (Kp = P / 128 PWM per tick).
        position_d_gain: default Position D Gain register value (Kd = D / 16).
        armature_kg_m2: reflected rotor + gear inertia [kg m^2] (estimate, see notes).
        friction_loss_nm: Coulomb friction of the gear train [N m].
        viscous_damping_nm_s: gear-train viscous damping beyond back-EMF [N m s / rad].
        notes: where the numbers come from.
    """

    model: str
    nominal_voltage_v: float
    stall_torque_nm: float
    no_load_speed_rad_s: float
    gear_ratio: float
    position_p_gain: int
    position_d_gain: int
    armature_kg_m2: float
    friction_loss_nm: float
    viscous_damping_nm_s: float
    notes: str = ""

    def __post_init__(self) -> None:
        for name in ("nominal_voltage_v", "stall_torque_nm", "no_load_speed_rad_s", "gear_ratio"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"servo {self.model}: {name} must be > 0")

    def stall_torque_at(self, voltage_v: float) -> float:
        """Stall torque [N m] at ``voltage_v`` (DC motor: proportional to voltage)."""
        return self.stall_torque_nm * voltage_v / self.nominal_voltage_v

    def no_load_speed_at(self, voltage_v: float) -> float:
        """No-load speed [rad/s] at ``voltage_v`` (proportional to voltage)."""
        return self.no_load_speed_rad_s * voltage_v / self.nominal_voltage_v

    @property
    def back_emf_damping_nm_s(self) -> float:
        """Viscous coefficient of the back-EMF, tau_stall / w_noload [N m s / rad]."""
        return self.stall_torque_nm / self.no_load_speed_rad_s

    def position_gain_nm_per_rad(self, voltage_v: float, p_gain: int | None = None) -> float:
        """Effective stiffness of the position loop before PWM saturation [N m / rad]."""
        p = self.position_p_gain if p_gain is None else p_gain
        kp_pwm_per_tick = p / 128.0
        return kp_pwm_per_tick * (TICKS_PER_REV / (2 * math.pi)) * self.stall_torque_at(voltage_v) / PWM_LIMIT

    def saturation_error_rad(self, p_gain: int | None = None) -> float:
        """Position error at which the PWM duty saturates [rad]."""
        p = self.position_p_gain if p_gain is None else p_gain
        return PWM_LIMIT / (p / 128.0) * 2 * math.pi / TICKS_PER_REV


def _rpm(x: float) -> float:
    return x * 2 * math.pi / 60.0


SERVO_DATASHEETS: dict[str, ServoDatasheet] = {
    s.model: s
    for s in (
        ServoDatasheet(
            model="XM430-W350",
            nominal_voltage_v=12.0,
            stall_torque_nm=4.1,  # e-manual: 4.1 N m at 12 V, 2.3 A
            no_load_speed_rad_s=_rpm(46.0),  # e-manual: 46 rpm at 12 V
            gear_ratio=353.5,
            position_p_gain=800,  # control table default (addr 84)
            position_d_gain=0,
            # Rotor ~0.07 g cm^2-class coreless motor times 353.5^2 plus gears: order 0.01 kg m^2.
            # Public OP3 models use 0.045, which we consider padded for simulator stability.
            armature_kg_m2=0.012,
            friction_loss_nm=0.03,  # public OP3 model
            viscous_damping_nm_s=0.05,
            notes="ROBOTIS e-manual XM430-W350; armature estimated",
        ),
        ServoDatasheet(
            model="XL430-W250",
            nominal_voltage_v=12.0,
            stall_torque_nm=1.5,  # e-manual: 1.5 N m at 12 V (1.4 at 11.1 V)
            no_load_speed_rad_s=_rpm(61.0),
            gear_ratio=258.5,
            position_p_gain=640,  # control table default
            position_d_gain=0,
            armature_kg_m2=0.005,
            friction_loss_nm=0.02,
            viscous_damping_nm_s=0.03,
            notes="ROBOTIS e-manual XL430-W250; armature estimated",
        ),
        ServoDatasheet(
            model="XM540-W270",
            nominal_voltage_v=12.0,
            stall_torque_nm=10.6,  # e-manual: 10.6 N m at 12 V
            no_load_speed_rad_s=_rpm(30.0),
            gear_ratio=272.5,
            position_p_gain=900,
            position_d_gain=0,
            armature_kg_m2=0.03,
            friction_loss_nm=0.05,
            viscous_damping_nm_s=0.08,
            notes="ROBOTIS e-manual XM540-W270; armature estimated",
        ),
        ServoDatasheet(
            model="MX-28(2.0)",
            nominal_voltage_v=12.0,
            stall_torque_nm=2.5,  # e-manual: 2.5 N m at 12 V
            no_load_speed_rad_s=_rpm(55.0),
            gear_ratio=193.0,
            position_p_gain=850,
            position_d_gain=0,
            armature_kg_m2=0.006,
            friction_loss_nm=0.02,
            viscous_damping_nm_s=0.03,
            notes="ROBOTIS e-manual MX-28(2.0); armature estimated",
        ),
    )
}


def servo_datasheet(model: str) -> ServoDatasheet:
    """Return the spec of a servo model, or raise ConfigError listing the known models."""
    try:
        return SERVO_DATASHEETS[model]
    except KeyError:
        raise ConfigError(
            f"unknown servo model {model!r}; known: {', '.join(sorted(SERVO_DATASHEETS))}",
            hint="add its numbers to robot_rise/servo.py SERVO_DATASHEETS",
        ) from None


def torque_limits(
    stall_torque_nm: np.ndarray, no_load_speed_rad_s: np.ndarray, velocity_rad_s: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Torque-speed envelope of a DC-motor servo at the given joint velocities.

    Args:
        stall_torque_nm: shape (n,) or broadcastable, [N m].
        no_load_speed_rad_s: shape (n,), [rad/s].
        velocity_rad_s: shape (..., n), [rad/s].

    Returns:
        (lower, upper) torque bounds [N m], each shaped like ``velocity_rad_s``.
    """
    r = np.asarray(velocity_rad_s) / no_load_speed_rad_s
    return -stall_torque_nm * (1.0 + r), stall_torque_nm * (1.0 - r)


def envelope_ratio(
    torque_nm: np.ndarray,
    velocity_rad_s: np.ndarray,
    stall_torque_nm: np.ndarray,
    no_load_speed_rad_s: np.ndarray,
) -> np.ndarray:
    """How much of the available torque is used: |tau| / (limit in tau's direction).

    1.0 means the servo is at its envelope; above 1 is impossible for a real servo. A torque
    against the motion (braking) has more room than stall, which the envelope reflects.

    Returns:
        ratio, shaped like ``torque_nm`` (dimensionless).
    """
    lower, upper = torque_limits(stall_torque_nm, no_load_speed_rad_s, velocity_rad_s)
    tau = np.asarray(torque_nm)
    room = np.where(tau >= 0, upper, -lower)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(room > 1e-9, np.abs(tau) / np.maximum(room, 1e-9), np.where(np.abs(tau) > 1e-9, np.inf, 0.0))
    return ratio


def position_mode_torque(
    goal_rad: np.ndarray,
    position_rad: np.ndarray,
    velocity_rad_s: np.ndarray,
    *,
    kp_nm_per_rad: np.ndarray,
    stall_torque_nm: np.ndarray,
    no_load_speed_rad_s: np.ndarray,
) -> np.ndarray:
    """Torque of a Dynamixel in position mode (P loop -> PWM saturation -> DC motor), [N m].

    All arrays shape (n,) or broadcastable; the result has the broadcast shape.
    """
    duty = np.clip(kp_nm_per_rad * (goal_rad - position_rad) / stall_torque_nm, -1.0, 1.0)
    return stall_torque_nm * (duty - velocity_rad_s / no_load_speed_rad_s)


@dataclass(frozen=True)
class ServoArrays:
    """Per-joint servo numbers at one supply voltage, as arrays (vectorised envelope checks).

    Attributes:
        stall_torque_nm: stall torque per joint at the voltage [N m], shape (n,).
        no_load_speed_rad_s: no-load speed per joint at the voltage [rad/s], shape (n,).
        kp_nm_per_rad: position-loop stiffness per joint [N m / rad], shape (n,).
        back_emf_damping_nm_s: tau_stall / w_noload per joint [N m s / rad], shape (n,).
    """

    stall_torque_nm: np.ndarray
    no_load_speed_rad_s: np.ndarray
    kp_nm_per_rad: np.ndarray
    back_emf_damping_nm_s: np.ndarray

    def motor_torque(self, actuator_force_nm: np.ndarray, velocity_rad_s: np.ndarray) -> np.ndarray:
        """Motor torque [N m] from the position-loop output and the joint speed.

        The MuJoCo position actuator gives ``tau_stall * clip(u)``; the back-EMF (modelled as joint
        damping) subtracts ``tau_stall * w / w_noload``. Shapes (..., n).
        """
        return np.asarray(actuator_force_nm) - self.back_emf_damping_nm_s * np.asarray(velocity_rad_s)

    def ratio(self, motor_torque_nm: np.ndarray, velocity_rad_s: np.ndarray) -> np.ndarray:
        """Torque / envelope ratio per joint (see :func:`envelope_ratio`), shape (..., n)."""
        return envelope_ratio(motor_torque_nm, velocity_rad_s, self.stall_torque_nm, self.no_load_speed_rad_s)


def servo_arrays(specs: tuple[ServoDatasheet, ...] | list[ServoDatasheet], voltage_v: float) -> ServoArrays:
    """Stack the per-joint servo numbers at ``voltage_v`` [V] into :class:`ServoArrays`."""

    def ro(values: list[float]) -> np.ndarray:
        a = np.array(values, dtype=float)
        a.setflags(write=False)
        return a

    return ServoArrays(
        stall_torque_nm=ro([s.stall_torque_at(voltage_v) for s in specs]),
        no_load_speed_rad_s=ro([s.no_load_speed_at(voltage_v) for s in specs]),
        kp_nm_per_rad=ro([s.position_gain_nm_per_rad(voltage_v) for s in specs]),
        back_emf_damping_nm_s=ro([s.back_emf_damping_nm_s for s in specs]),
    )
