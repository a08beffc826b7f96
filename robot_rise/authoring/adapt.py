"""Adapting a strategy to a robot's proportions: squatting and standing keyframes balanced over the feet.

A strategy's keyframes are written for one body. On another, a keyframe the robot holds on its
feet alone (the squat, the stand) puts the centre of mass ahead of or behind the feet if the legs,
torso or mass distribution differ (paper 000 section 5.3: the dynamics filter adapts the motion
to the body; here the posture part of it, before timing). For each such keyframe -- both soles flat
on the ground and nothing else within ``FEET_ONLY_CLEARANCE_M`` of it -- the torso is leaned about
the ankles (hip pitch -t, ankle pitch +t: the soles stay flat) until the centre of mass lies over
the middle of the feet.
"""

from __future__ import annotations

from collections.abc import Mapping

import mujoco
import numpy as np
from scipy.optimize import brentq

from robot_rise.model import Robot, compose, model_index

__all__ = ["FEET_ONLY_CLEARANCE_M", "MAX_LEAN_RAD", "balance_on_feet"]

FEET_ONLY_CLEARANCE_M = 0.02  # a keyframe is "on its feet alone" when nothing else is this close to the ground
MAX_LEAN_RAD = 0.5  # the lean correction is searched within +-this


class _Statics:
    """Robot-alone kinematics: a posture placed with its soles flat on z = 0."""

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self.m = compose(robot, None, with_actuators=False)
        self.d = mujoco.MjData(self.m)
        self.idx = model_index(self.m, robot)
        self.soles = [mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_SITE, s) for s in robot.sole_sites]
        # a foot is everything from the ankle pitch joint down (the link between the ankle joints too)
        self.feet = {int(self.m.site_bodyid[s]) for s in self.soles}
        if robot.roles is not None:
            for side in ("left", "right"):
                ankle = robot.roles.by_role().get(f"{side}.ankle_pitch")
                if ankle is not None:
                    self.feet.add(int(self.m.jnt_bodyid[mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_JOINT, ankle.joint)]))
        root = self.idx.root_body
        self.foot_geoms = np.array([g for g in range(self.m.ngeom) if self._in_feet(int(self.m.geom_bodyid[g]))], dtype=int)
        self.other_geoms = np.array([g for g in range(self.m.ngeom) if g not in set(self.foot_geoms.tolist()) and self.m.geom_bodyid[g] != 0], dtype=int)
        self.root = root
        # the soles' orientation in the root frame at the zero pose: "flat" is that orientation
        self.d.qpos[self.idx.qpos_root] = [0, 0, 0, 1, 0, 0, 0]
        self.d.qpos[self.idx.qpos_joints] = 0.0
        mujoco.mj_kinematics(self.m, self.d)
        self.sole_zero = self.d.site_xmat[self.soles[0]].reshape(3, 3).copy()

    def _in_feet(self, body: int) -> bool:
        while body > 0:
            if body in self.feet:
                return True
            body = int(self.m.body_parentid[body])
        return False

    def place(self, q: np.ndarray) -> None:
        d, m, idx = self.d, self.m, self.idx
        d.qpos[idx.qpos_root] = [0, 0, 0, 1, 0, 0, 0]
        d.qpos[idx.qpos_joints] = q
        mujoco.mj_kinematics(m, d)
        R = d.site_xmat[self.soles[0]].reshape(3, 3)  # first sole's frame in the root frame
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, (self.sole_zero @ R.T).ravel())  # root turned so the sole is as at zero pose
        d.qpos[idx.qpos_root[3:]] = quat
        mujoco.mj_kinematics(m, d)
        z = min(d.site_xpos[s][2] for s in self.soles)
        d.qpos[idx.qpos_root[2]] = -z
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)

    def lowest(self, geoms: np.ndarray) -> float:
        """Lowest corner of the geoms' oriented bounding boxes [m]."""
        d, m = self.d, self.m
        z = np.inf
        for g in geoms:
            R = d.geom_xmat[g].reshape(3, 3)
            c = d.geom_xpos[g][2] + R[2] @ m.geom_aabb[g, :3]
            z = min(z, c - float(np.abs(R[2]) @ m.geom_aabb[g, 3:]))
        return float(z)

    def com_offset_x(self) -> float:
        """CoM x minus the middle of the sole sites [m]."""
        mid = np.mean([self.d.site_xpos[s] for s in self.soles], axis=0)
        return float(self.d.subtree_com[self.root][0] - mid[0])


def balance_on_feet(
    robot: Robot, keyframes: tuple[tuple[float, Mapping[str, float]], ...], start: Mapping[str, float], *, from_keyframe: int = 0
) -> tuple[tuple[tuple[float, dict[str, float]], ...], list[str]]:
    """Lean each on-its-feet keyframe so the centre of mass is over the feet (see the module docstring).

    Args:
        keyframes: (time, joint goals) as a strategy maps onto the robot; goals not named hold.
        start: the joint angles before the first keyframe.
        from_keyframe: keyframes before this one are left alone (the lying-to-sitting phase, where
            soles flat on the ground would be a posture the robot is not in).

    Returns:
        the keyframes with leaned hip and ankle pitch goals, and a note per changed keyframe.
    """
    roles = robot.roles
    if roles is None:
        return tuple((t, dict(g)) for t, g in keyframes), []
    by_role = roles.by_role()
    pitch = {side: (by_role.get(f"{side}.hip_pitch"), by_role.get(f"{side}.ankle_pitch")) for side in ("left", "right")}
    if any(h is None or a is None for h, a in pitch.values()):
        return tuple((t, dict(g)) for t, g in keyframes), ["no hip or ankle pitch: keyframes not balanced"]
    st = _Statics(robot)
    names = robot.joint_names
    current = np.array([start.get(j, 0.0) for j in names])
    out, notes = [], []
    for i, (t, goals) in enumerate(keyframes):
        q = current.copy()
        for j, v in goals.items():
            q[names.index(j)] = v
        q = np.clip(q, robot.joint_lower, robot.joint_upper)
        st.place(q)
        new_goals = dict(goals)
        if i >= from_keyframe and st.lowest(st.other_geoms) > FEET_ONLY_CLEARANCE_M:

            def leaned(lean: float) -> np.ndarray:
                ql = q.copy()
                for hip, ankle in pitch.values():
                    ql[names.index(hip.joint)] += -lean * hip.sign  # hip pitch role -lean: the torso forward
                    ql[names.index(ankle.joint)] += lean * ankle.sign
                return np.clip(ql, robot.joint_lower, robot.joint_upper)

            def offset(lean: float) -> float:
                st.place(leaned(lean))
                return st.com_offset_x()

            before = offset(0.0)
            try:
                lean = brentq(offset, -MAX_LEAN_RAD, MAX_LEAN_RAD, xtol=1e-3)
            except ValueError:
                lean = 0.0
            if abs(lean) > 1e-3:
                q = leaned(lean)
                for hip, ankle in pitch.values():
                    new_goals[hip.joint] = float(q[names.index(hip.joint)])
                    new_goals[ankle.joint] = float(q[names.index(ankle.joint)])
                notes.append(f"keyframe {i} (t {t:.2f} s) on its feet: CoM {1000 * before:+.0f} mm from the feet, leaned {np.degrees(lean):+.1f} deg")
        out.append((t, new_goals))
        current = q
    return tuple(out), notes
