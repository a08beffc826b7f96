"""Keyframes and the authored motion: a motion written as joint goals at times, joined into a trajectory.

Each motion is a list of keyframes (time [s], joint goals); the rows of the trajectory are the
keyframes joined by a shape-preserving cubic (PCHIP) sampled at ``ROW_HZ``, starting from the
settled start posture (the first row is its joint angles: no goal jump).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import PchipInterpolator

from robot_rise.library.strategies import KeyframedMotion
from robot_rise.model import Robot
from robot_rise.posture import Posture
from robot_rise.trajectory import Trajectory

__all__ = ["ROW_HZ", "Keyframe", "MotionSpec", "build_trajectory"]

ROW_HZ = 100.0  # trajectory rows per second (the servo goal update rate) [Hz]


@dataclass(frozen=True)
class Keyframe:
    """Joint goals reached at time ``t_s`` [s]; joints not named keep the previous keyframe's goal."""

    t_s: float
    joints: Mapping[str, float]


@dataclass(frozen=True, kw_only=True)
class MotionSpec(KeyframedMotion[Keyframe]):
    """One library motion as authored: a strategy mapped onto a robot's joints.

    Attributes (besides those of :class:`~robot_rise.library.strategies.KeyframedMotion`):
        strategy: one line for people (the strategy's description).
        lying_joints: joint angles of the lying posture before settling [rad].
    """

    strategy: str
    lying_joints: Mapping[str, float]


def build_trajectory(robot: Robot, start: Posture, keyframes: tuple[Keyframe, ...], *, row_hz: float = ROW_HZ) -> Trajectory:
    """Join the start joints and the keyframes with a shape-preserving cubic (PCHIP), sampled at ``row_hz``.

    Returns:
        a Trajectory with rows every 1 / row_hz seconds (plus the final keyframe time).
    """
    names = robot.joint_names
    q0 = start.joint_vector(names)
    times = [0.0]
    goals = [q0]
    for kf in keyframes:
        if kf.t_s <= times[-1]:
            raise ValueError(f"keyframe times must increase: {kf.t_s} after {times[-1]}")
        unknown = set(kf.joints) - set(names)
        if unknown:
            raise ValueError(f"unknown joints {sorted(unknown)}")
        g = goals[-1].copy()
        for j, v in kf.joints.items():
            g[names.index(j)] = v
        goals.append(np.clip(g, robot.joint_lower, robot.joint_upper))
        times.append(kf.t_s)
    T = times[-1]
    t = np.arange(0.0, T, 1.0 / row_hz)
    t = np.append(t[t < T - 1e-9], T)
    # Shape-preserving cubic through the keyframes: no overshoot past a keyframe (so no joint
    # limit is crossed), velocity continuous, zero at the start and end.
    g = np.array(goals)
    q = PchipInterpolator(np.array(times), g, axis=0)(t)
    q = np.clip(q, robot.joint_lower, robot.joint_upper)
    q[0] = q0  # the settled start, even where the ground pressed a joint a hair past its limit
    return Trajectory(robot.name, names, t, q, start)

