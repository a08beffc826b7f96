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
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Protocol, runtime_checkable

if TYPE_CHECKING:
    from drivers.servo_map import ServoMap

__all__ = ["ServoCommand", "ServoMotion", "Plant", "JointPlant", "ServoFramePlant", "KinematicPlant"]


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
