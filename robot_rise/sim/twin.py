"""The physics twin: a MuJoCo simulation of the robot that moves the emulated servos.

The mock bus (``drivers.mockbus``) asks its *plant* to advance by ``dt`` given each servo's
command and reads back each shaft's motion. :class:`MujocoTwin` is such a plant in the joint
frame: it satisfies ``drivers.mockbus.JointPlant`` structurally (duck typing; this module never
imports ``drivers``), and the bus puts it on the servo IDs and servo frame through the servo map:

- ``advance_joints(dt_s, commands)`` takes ``{joint: command}`` where a command has the attributes
  ``torque_on``, ``goal_rad`` (joint angle) and ``pwm_fraction`` (0..1, output limit), and
  returns ``{joint: motion}`` with ``position_rad``, ``velocity_rad_s`` and ``torque_nm``.

The simulated robot is the composed model of :func:`robot_rise.model.compose` (robot + scene +
one position servo per joint, the same servo model the player uses), stepped at its own
timestep (2 ms). A servo with torque off (or zero PWM) exerts no position-loop force; its
joint keeps the passive damping and friction of the gear train. Goal PWM below 100 % scales
the torque limit.

The twin also feeds the bus's IMU (``drivers.mockbus.ImuSource``, structurally): ``imu_state()``
gives the true inertial state of the root body (the torso, whose frame is the robot's: x
forward, y left, z up for the OP3): its orientation, its angular velocity in its own frame (the
free joint's rotational velocity, which MuJoCo keeps in the body frame) and the specific force an
accelerometer at the root body's origin measures, ``R^T (a - g)``, with ``a`` the free joint's
linear acceleration (world frame) of the last physics step.

Disturbances (tests and the guard's push benchmark): ``push(force_world_n, duration_s)`` applies
a constant force at the root body's centre of mass for that much simulated time from now, as a
hand shoving the torso would.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

import mujoco
import numpy as np

from robot_rise.constants import STAND_MAX_TILT_RAD, STAND_MIN_HEIGHT_FRACTION
from robot_rise.errors import ConfigError
from robot_rise.model import ModelIndex, Robot, compose, model_index
from robot_rise.posture import Posture, posture_from_qpos, stand_posture
from robot_rise.linkage import close_loops

__all__ = ["ServoCommandLike", "TwinMotion", "TwinState", "TwinImuState", "MujocoTwin"]

log = logging.getLogger(__name__)


class ServoCommandLike(Protocol):
    """What the twin reads of a mock servo's command (``drivers.mockbus.ServoCommand``)."""

    @property
    def torque_on(self) -> bool: ...

    @property
    def goal_rad(self) -> float: ...

    @property
    def pwm_fraction(self) -> float: ...


@dataclass(frozen=True)
class TwinMotion:
    """One joint's state after a step (read by the mock servo through the servo map).

    Attributes:
        position_rad: joint angle [rad].
        velocity_rad_s: joint velocity [rad/s].
        torque_nm: motor torque on the joint [N m].
    """

    position_rad: float
    velocity_rad_s: float = 0.0
    torque_nm: float = 0.0


@dataclass(frozen=True)
class TwinState:
    """A summary of the simulated robot for the operator.

    Attributes:
        t_s: simulated time [s].
        joint_names: joint order of ``q_rad``.
        q_rad: joint angles [rad], shape (n,).
        root_pos: root position [m], shape (3,).
        tilt_rad: angle between the torso's z axis and the world vertical [rad].
        torso_height_m: torso site height above the lowest sole site [m].
        stand_height_m: the same height in the ``stand`` keyframe [m].
    """

    t_s: float
    joint_names: tuple[str, ...]
    q_rad: np.ndarray
    root_pos: np.ndarray
    tilt_rad: float
    torso_height_m: float
    stand_height_m: float

    @property
    def upright(self) -> bool:
        """Upright now by the standing judge's thresholds (tilt and height; the judge also
        asks for the feet-only contact and a hold time, which one instant cannot show)."""
        return (self.tilt_rad <= STAND_MAX_TILT_RAD
                and self.torso_height_m >= STAND_MIN_HEIGHT_FRACTION * self.stand_height_m)


@dataclass(frozen=True)
class TwinImuState:
    """The true inertial state of the root body (read by the mock bus's IMU).

    Attributes:
        t_s: simulated time [s].
        quat_wxyz: root body orientation in the world (w, x, y, z).
        angular_velocity_rad_s: root body angular velocity in the root body frame [rad/s], 3 values.
        specific_force_m_s2: ``R^T (a - g)`` at the root body origin, root body frame [m/s^2],
            3 values (+9.81 along the body's z at rest upright).
    """

    t_s: float
    quat_wxyz: tuple[float, float, float, float]
    angular_velocity_rad_s: tuple[float, float, float]
    specific_force_m_s2: tuple[float, float, float]


class MujocoTwin:
    """A MuJoCo simulation of ``robot`` in ``scene`` driven by servo commands.

    Args:
        robot: the loaded robot.
        scene: scene name or MJCF path (see :func:`robot_rise.model.compose`).
        start: posture at t = 0, at rest (default: the ``stand`` keyframe).
        voltage_v: servo supply voltage [V] (None: the robot's own).
        hold_start: until the first servo is torqued on, every joint holds the start posture
            (as if the robot were held there while the driver configures the servos with
            torque off); afterwards the servos' own commands rule.

    Not thread-safe (owns one MjData).
    """

    def __init__(self, robot: Robot, scene: str | os.PathLike[str] | None = "flat", *,
                 start: Posture | None = None, voltage_v: float | None = None,
                 hold_start: bool = True) -> None:
        self.robot = robot
        self.model = compose(robot, scene, with_actuators=True, voltage_v=voltage_v)
        self.data = mujoco.MjData(self.model)
        self.index: ModelIndex = model_index(self.model, robot)
        if self.index.actuators.size != robot.n_joints:
            raise ConfigError(f"composed model has {self.index.actuators.size} servos for {robot.n_joints} joints")
        m = self.model
        acts = self.index.actuators
        self._kp = m.actuator_gainprm[acts, 0].copy()
        self._force_limit = m.actuator_forcerange[acts, 1].copy()
        self._ctrl_lo = m.actuator_ctrlrange[acts, 0].copy()
        self._ctrl_hi = m.actuator_ctrlrange[acts, 1].copy()
        self._column = {name: k for k, name in enumerate(robot.joint_names)}
        self._goal = np.zeros(robot.n_joints)
        self._powered = np.zeros(robot.n_joints, dtype=bool)
        self._pwm = np.ones(robot.n_joints)
        self._pending_s = 0.0
        self.hold_start = hold_start
        self._holding = hold_start
        self._push_force = np.zeros(3)
        self._push_until_s = -np.inf
        self._torso_site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, robot.torso_site)
        self._sole_sites = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, s) for s in robot.sole_sites]
        self.reset(start if start is not None else stand_posture(robot))

    # ---- state --------------------------------------------------------------------------
    def reset(self, start: Posture) -> None:
        """Put the robot at rest in ``start``; servos unpowered, goals at the start angles."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        d.qpos[:] = start.qpos(self.robot, self.index, m.qpos0)
        if self.index.linkage is not None:  # the passive joints where the driven ones put them
            close_loops(m, d, self.index.linkage)
        d.qvel[:] = 0.0
        self._goal = np.clip(start.joint_vector(self.robot.joint_names), self._ctrl_lo, self._ctrl_hi)
        self._powered[:] = self.hold_start
        self._holding = self.hold_start
        self._pwm[:] = 1.0
        self._pending_s = 0.0
        self._push_until_s = -np.inf
        self._apply_servo_state()
        mujoco.mj_forward(m, d)

    def push(self, force_world_n: Sequence[float], duration_s: float) -> None:
        """Push the root body: ``force_world_n`` [N] (world frame, 3 values) at its centre of
        mass for ``duration_s`` [s] of simulated time from now (the impulse is their product).

        Raises:
            ValueError: a non-finite force or a negative duration.
        """
        f = np.asarray(force_world_n, dtype=float).reshape(3)
        if not (np.all(np.isfinite(f)) and np.isfinite(duration_s) and duration_s >= 0.0):
            raise ValueError(f"push needs a finite force and a duration >= 0, got {tuple(f)} N for {duration_s} s")
        self._push_force = f
        self._push_until_s = float(self.data.time) + float(duration_s)

    @property
    def time_s(self) -> float:
        """Simulated time [s]."""
        return float(self.data.time)

    @property
    def joint_positions_rad(self) -> np.ndarray:
        """Joint angles [rad] in the robot's joint order, shape (n,)."""
        return self.data.qpos[self.index.qpos_joints].copy()

    def posture(self) -> Posture:
        """The simulated robot's present posture."""
        return posture_from_qpos(self.robot, self.index, self.data.qpos)

    def state(self) -> TwinState:
        """A summary for the operator (torso tilt and height: is the robot standing?)."""
        d = self.data
        zt = d.site_xmat[self._torso_site].reshape(3, 3)[:, 2]
        sole_z = min(float(d.site_xpos[s][2]) for s in self._sole_sites)
        return TwinState(
            t_s=float(d.time),
            joint_names=self.robot.joint_names,
            q_rad=self.joint_positions_rad,
            root_pos=d.qpos[self.index.qpos_root[:3]].copy(),
            tilt_rad=float(np.arccos(np.clip(zt[2], -1.0, 1.0))),
            torso_height_m=float(d.site_xpos[self._torso_site][2]) - sole_z,
            stand_height_m=self.robot.stand_height_m,
        )

    def imu_state(self) -> TwinImuState:
        """The root body's orientation, angular velocity and specific force now (true values)."""
        m, d = self.model, self.data
        root_q = self.index.qpos_root
        root_v = self.index.qvel_root
        quat = d.qpos[root_q[3:7]]
        mat = np.zeros(9)
        mujoco.mju_quat2Mat(mat, quat / np.linalg.norm(quat))
        rot = mat.reshape(3, 3)  # body to world
        force = rot.T @ (d.qacc[root_v[:3]] - m.opt.gravity)
        w = d.qvel[root_v[3:6]]
        return TwinImuState(float(d.time), (float(quat[0]), float(quat[1]), float(quat[2]), float(quat[3])),
                            (float(w[0]), float(w[1]), float(w[2])), (float(force[0]), float(force[1]), float(force[2])))

    # ---- the Plant protocol -------------------------------------------------------------
    def advance_joints(self, dt_s: float, commands: Mapping[str, ServoCommandLike]) -> dict[str, TwinMotion]:
        """Apply ``commands`` (by joint name, goals as joint angles), integrate ``dt_s`` [s], return
        every joint's motion.

        Time is accumulated: physics steps happen whenever a whole timestep has passed, so
        calls with ``dt_s`` shorter than the timestep are exact on average.
        """
        if self._holding and any(cmd.torque_on for cmd in commands.values()):
            self._holding = False
            log.debug("twin: first servo torqued on; servos now follow their commands")
        if commands and not self._holding:
            goal = np.zeros(len(self._goal))
            have = np.zeros(len(self._goal), dtype=bool)
            for joint, cmd in commands.items():
                k = self._column.get(joint)
                if k is None:
                    continue
                have[k] = True
                goal[k] = cmd.goal_rad
                self._powered[k] = bool(cmd.torque_on) and cmd.pwm_fraction > 0.0
                self._pwm[k] = min(1.0, max(0.0, float(cmd.pwm_fraction)))
            goal = np.clip(goal, self._ctrl_lo, self._ctrl_hi)
            self._goal = np.where(have, goal, self._goal)
            self._apply_servo_state()
        self._pending_s += max(0.0, dt_s)
        timestep = float(self.model.opt.timestep)
        n_steps = int(self._pending_s / timestep + 1e-9)
        if n_steps:
            self._pending_s -= n_steps * timestep
            self._step(n_steps)
        return self._motions()

    def _step(self, n_steps: int) -> None:
        """``n_steps`` physics steps, a push (if one is on) applied while it lasts."""
        m, d = self.model, self.data
        root = self.index.root_body
        left_s = self._push_until_s - float(d.time)
        pushing = math.ceil(left_s / float(m.opt.timestep) - 1e-9) if left_s > 0.0 else 0
        if pushing:
            k = min(pushing, n_steps)
            d.xfrc_applied[root, :3] = self._push_force
            mujoco.mj_step(m, d, nstep=k)
            d.xfrc_applied[root, :3] = 0.0
            n_steps -= k
        if n_steps:
            mujoco.mj_step(m, d, nstep=n_steps)

    def _apply_servo_state(self) -> None:
        m, d = self.model, self.data
        acts = self.index.actuators
        kp = np.where(self._powered, self._kp, 0.0)
        m.actuator_gainprm[acts, 0] = kp
        m.actuator_biasprm[acts, 1] = -kp
        limit = self._force_limit * np.where(self._powered, self._pwm, 1.0)
        m.actuator_forcerange[acts, 0] = -limit
        m.actuator_forcerange[acts, 1] = limit
        d.ctrl[acts] = self._goal

    def _motions(self) -> dict[str, TwinMotion]:
        d = self.data
        q = d.qpos[self.index.qpos_joints]
        qd = d.qvel[self.index.dof_joints]
        force = d.actuator_force[self.index.actuators]
        return {joint: TwinMotion(float(q[k]), float(qd[k]), float(force[k])) for joint, k in self._column.items()}
