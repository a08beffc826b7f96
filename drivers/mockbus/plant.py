"""The ``Plant`` extension point: what moves the emulated servos' shafts.

The emulator asks the plant to advance by ``dt`` given each servo's command and reads back
each shaft's motion. Angles here are in the *servo frame*: ``(ticks - 2048) * 2 pi / 4096`` [rad]
(no direction or zero offset). A plant that speaks joint angles by joint name, such as the
physics twin (:class:`JointPlant`), is put on the bus through :class:`ServoFramePlant`, which
converts with the servo map's own conversion (``drivers.servo_map``: one place for it).

The default :class:`KinematicPlant` is a first-order servo with a speed limit: fast, no MuJoCo.
The physics twin ``robot_rise.sim.twin.MujocoTwin`` satisfies :class:`JointPlant` structurally
(this package never imports ``robot_rise``); ``robot-rise execute --mock --twin`` and
``robot-rise mockbus serve --twin`` wire it in.

The IMU hook: a plant that also knows how the robot's body moves offers ``imu_state()``
(:class:`ImuSource`), the true inertial state of the body the IMU sits on, in that body's frame:
orientation (quaternion w, x, y, z of the body in the world), angular velocity [rad/s] and
specific force [m/s^2] (what an accelerometer measures: ``R^T (a - g)``, so +9.81 m/s^2 along
the body's up axis at rest). The emulated IMU (:mod:`drivers.mockbus.emulated_imu`) reads it
through :func:`imu_source_of` and adds the sensor errors of :class:`ImuNoise` (seeded).
"""

from __future__ import annotations

import math
import random
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Protocol, runtime_checkable

if TYPE_CHECKING:
    from drivers.servo_map import ServoMap

__all__ = ["ServoCommand", "ServoMotion", "Plant", "JointPlant", "ServoFramePlant", "KinematicPlant",
           "STANDARD_GRAVITY_M_S2", "ImuStateLike", "ImuState", "ImuSource", "ImuNoise", "imu_source_of"]

STANDARD_GRAVITY_M_S2 = 9.80665  # [m/s^2] standard gravity (what an accelerometer at rest reads)


@dataclass(frozen=True)
class ServoCommand:
    """What one servo asks of its shaft during the next step.

    Attributes:
        torque_on: motor powered.
        goal_rad: goal position, servo frame [rad].
        max_speed_rad_s: speed limit [rad/s] (profile velocity, or the no-load speed).
        pwm_fraction: output limit 0..1 (Goal PWM / PWM limit); 0 acts like torque off.
        stall_torque_nm: servo stall torque [N m].
        stiffness_nm_per_rad: position-loop stiffness [N m/rad] (P gain model).
    """

    torque_on: bool
    goal_rad: float
    max_speed_rad_s: float
    pwm_fraction: float = 1.0
    stall_torque_nm: float = 4.1
    stiffness_nm_per_rad: float = 19.0


@dataclass(frozen=True)
class ServoMotion:
    """Shaft state after a step.

    Attributes:
        position_rad: servo frame [rad].
        velocity_rad_s: [rad/s].
        torque_nm: motor torque [N m] (sets the reported current / load).
    """

    position_rad: float
    velocity_rad_s: float = 0.0
    torque_nm: float = 0.0


@runtime_checkable
class Plant(Protocol):
    """Moves the shafts of the servos on an emulated bus."""

    def advance(self, dt_s: float, commands: Mapping[int, ServoCommand]) -> Mapping[int, ServoMotion]:
        """Integrate ``dt_s`` [s] with ``commands`` (by servo ID); return every servo's motion."""
        ...


class MotionLike(Protocol):
    """A shaft's state as a joint-frame plant reports it (:class:`ServoMotion`'s attributes)."""

    @property
    def position_rad(self) -> float: ...

    @property
    def velocity_rad_s(self) -> float: ...

    @property
    def torque_nm(self) -> float: ...


@runtime_checkable
class JointPlant(Protocol):
    """A plant in the joint frame: commands and motions by joint name, angles in radians."""

    def advance_joints(self, dt_s: float, commands: Mapping[str, ServoCommand]) -> Mapping[str, MotionLike]:
        """Integrate ``dt_s`` [s] with ``commands`` (by joint, goal as a joint angle); return every joint's motion."""
        ...


class ServoFramePlant:
    """A :class:`JointPlant` on the bus: servo IDs and servo-frame angles in, through ``servo_map``.

    Args:
        plant: the joint-frame plant (e.g. the physics twin).
        servo_map: which servo drives which joint, with its direction and zero offset.
    """

    def __init__(self, plant: JointPlant, servo_map: "ServoMap") -> None:
        self.plant = plant
        self._by_id = {s.id: s for s in servo_map.servos}

    def advance(self, dt_s: float, commands: Mapping[int, ServoCommand]) -> dict[int, ServoMotion]:
        by_joint = {self._by_id[sid].joint: replace(cmd, goal_rad=self._by_id[sid].from_servo_frame(cmd.goal_rad))
                    for sid, cmd in commands.items() if sid in self._by_id}
        motions = self.plant.advance_joints(dt_s, by_joint)
        out = {}
        for sid, servo in self._by_id.items():
            m = motions.get(servo.joint)
            if m is not None:  # velocity and torque change sign with the direction, not the offset
                out[sid] = ServoMotion(servo.to_servo_frame(m.position_rad), servo.direction * m.velocity_rad_s,
                                       servo.direction * m.torque_nm)
        return out


class KinematicPlant:
    """First-order position servo with a speed limit, no dynamics, no gravity.

    Args:
        time_constant_s: position time constant [s].
        load_torque_nm: constant external torque every joint holds [N m] (heats servos).
        initial_rad: starting shaft angles by servo ID (servo frame [rad]); others start at 0.
    """

    def __init__(self, *, time_constant_s: float = 0.03, load_torque_nm: float = 0.3,
                 initial_rad: Mapping[int, float] | None = None) -> None:
        self.time_constant_s = time_constant_s
        self.load_torque_nm = load_torque_nm
        self._pos: dict[int, float] = dict(initial_rad or {})
        self._vel: dict[int, float] = {}

    def set_position(self, servo_id: int, position_rad: float) -> None:
        """Move a shaft by hand (servo frame [rad]), e.g. posing the robot with torque off."""
        self._pos[servo_id] = position_rad
        self._vel[servo_id] = 0.0

    def advance(self, dt_s: float, commands: Mapping[int, ServoCommand]) -> Mapping[int, ServoMotion]:
        out = {}
        for sid, cmd in commands.items():
            pos = self._pos.get(sid, 0.0)
            if cmd.torque_on and cmd.pwm_fraction > 0.0 and dt_s > 0:
                err = cmd.goal_rad - pos
                step = err * (1.0 - math.exp(-dt_s / self.time_constant_s))
                vmax = cmd.max_speed_rad_s * cmd.pwm_fraction
                step = max(-vmax * dt_s, min(vmax * dt_s, step))
                new = pos + step
                vel = step / dt_s
                err_after = cmd.goal_rad - new
                torque = max(-cmd.stall_torque_nm, min(cmd.stall_torque_nm,
                             cmd.stiffness_nm_per_rad * err_after + self.load_torque_nm))
                torque *= cmd.pwm_fraction
            else:
                new, vel, torque = pos, 0.0, 0.0
            self._pos[sid] = new
            self._vel[sid] = vel
            out[sid] = ServoMotion(new, vel, torque)
        return out


# ---- the IMU hook ----------------------------------------------------------------------------


class ImuStateLike(Protocol):
    """The inertial state of the body the IMU sits on (:class:`ImuState`'s attributes)."""

    @property
    def t_s(self) -> float: ...

    @property
    def quat_wxyz(self) -> tuple[float, float, float, float]: ...

    @property
    def angular_velocity_rad_s(self) -> tuple[float, float, float]: ...

    @property
    def specific_force_m_s2(self) -> tuple[float, float, float]: ...


@dataclass(frozen=True)
class ImuState:
    """The true inertial state of the IMU's body, in the body frame.

    Attributes:
        t_s: plant time of the state [s].
        quat_wxyz: orientation of the body in the world (unit quaternion w, x, y, z).
        angular_velocity_rad_s: body angular velocity in the body frame [rad/s], 3 values.
        specific_force_m_s2: ``R^T (a - g)`` in the body frame [m/s^2], 3 values (at rest
            upright: (0, 0, +9.81)).
    """

    t_s: float = 0.0
    quat_wxyz: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    angular_velocity_rad_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    specific_force_m_s2: tuple[float, float, float] = (0.0, 0.0, STANDARD_GRAVITY_M_S2)

    def __post_init__(self) -> None:
        for name, n in (("quat_wxyz", 4), ("angular_velocity_rad_s", 3), ("specific_force_m_s2", 3)):
            value = tuple(float(v) for v in getattr(self, name))
            if len(value) != n or not all(math.isfinite(v) for v in value):
                raise ValueError(f"ImuState.{name} needs {n} finite values, got {getattr(self, name)!r}")
            object.__setattr__(self, name, value)
        norm = math.sqrt(sum(v * v for v in self.quat_wxyz))
        if not 0.5 < norm < 1.5:
            raise ValueError(f"ImuState.quat_wxyz {self.quat_wxyz} is not a unit quaternion")
        object.__setattr__(self, "quat_wxyz", tuple(v / norm for v in self.quat_wxyz))


@runtime_checkable
class ImuSource(Protocol):
    """A plant that knows how the IMU's body moves (the physics twin is one)."""

    def imu_state(self) -> ImuStateLike:
        """The body's inertial state now (true values, no sensor errors)."""
        ...


def imu_source_of(plant: object) -> ImuSource | None:
    """The IMU hook of ``plant``, looking through a :class:`ServoFramePlant`; ``None`` if it has none."""
    if isinstance(plant, ImuSource):
        return plant
    inner = plant.plant if isinstance(plant, ServoFramePlant) else None
    return inner if isinstance(inner, ImuSource) else None


def _vector3(name: str, value: tuple[float, ...]) -> tuple[float, float, float]:
    v = tuple(float(x) for x in value)
    if len(v) != 3 or not all(math.isfinite(x) for x in v):
        raise ValueError(f"ImuNoise.{name} needs 3 finite values, got {value!r}")
    return v  # type: ignore[return-value]


def _quat_mul(a: tuple[float, ...], b: tuple[float, ...]) -> tuple[float, float, float, float]:
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw)


@dataclass(frozen=True)
class ImuNoise:
    """Sensor errors the emulated IMU adds to the plant's true state (all zero: a perfect IMU).

    Attributes:
        gyro_noise_rad_s: white noise per axis and sample, standard deviation [rad/s].
        accel_noise_m_s2: white noise per axis and sample, standard deviation [m/s^2].
        gyro_bias_rad_s: constant offset per axis [rad/s] (body frame).
        accel_bias_m_s2: constant offset per axis [m/s^2] (body frame).
        orientation_noise_rad: white noise of the fused orientation, a random rotation with
            this standard deviation per axis [rad].
        seed: seed of the noise generator (the same seed gives the same samples).
    """

    gyro_noise_rad_s: float = 0.0
    accel_noise_m_s2: float = 0.0
    gyro_bias_rad_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    accel_bias_m_s2: tuple[float, float, float] = (0.0, 0.0, 0.0)
    orientation_noise_rad: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("gyro_noise_rad_s", "accel_noise_m_s2", "orientation_noise_rad"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"ImuNoise.{name} must be a finite standard deviation >= 0, got {value}")
        object.__setattr__(self, "gyro_bias_rad_s", _vector3("gyro_bias_rad_s", self.gyro_bias_rad_s))
        object.__setattr__(self, "accel_bias_m_s2", _vector3("accel_bias_m_s2", self.accel_bias_m_s2))

    def rng(self) -> random.Random:
        """A fresh noise generator seeded with :attr:`seed`."""
        return random.Random(self.seed)

    def apply(self, state: ImuStateLike, rng: random.Random) -> ImuState:
        """``state`` as the sensor reports it: bias and noise added (drawn from ``rng``)."""
        gauss = rng.gauss
        sg, sa, so = self.gyro_noise_rad_s, self.accel_noise_m_s2, self.orientation_noise_rad
        w = tuple(v + b + (gauss(0.0, sg) if sg else 0.0)
                  for v, b in zip(state.angular_velocity_rad_s, self.gyro_bias_rad_s))
        f = tuple(v + b + (gauss(0.0, sa) if sa else 0.0)
                  for v, b in zip(state.specific_force_m_s2, self.accel_bias_m_s2))
        q = tuple(state.quat_wxyz)
        if so:
            rx, ry, rz = gauss(0.0, so), gauss(0.0, so), gauss(0.0, so)
            angle = math.sqrt(rx * rx + ry * ry + rz * rz)
            if angle > 0.0:
                s = math.sin(angle / 2) / angle
                q = _quat_mul(q, (math.cos(angle / 2), rx * s, ry * s, rz * s))  # a rotation in the body frame
        return ImuState(state.t_s, q, w, f)  # type: ignore[arg-type]
