"""The standing posture of an imported robot: searched in roles (upright, soles flat, knees bent, centre of mass over the feet).

Candidates bend the knees by ``2a`` with the hips and ankles taking ``a`` each (soles parallel
to the ground), lean the torso by ``t`` about the ankles so that the centre of mass lies over the
middle of the soles, open the arms a little (clear of the torso) and keep everything else at the
neutral pose. The first candidate that stands free of self collision, with the centre of mass
inside the support polygon, wins; the dynamic check (holding it with the servos) happens once
the robot directory exists (:func:`robot_rise.robot_import.importer.import_robot`).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from scipy.optimize import brentq

from robot_rise.placement import place_on_soles
from robot_rise.robot_import.roles import geom_points, subtree_geoms
from robot_rise.roles import RoleMap

__all__ = ["StandCandidate", "stand_candidates", "KNEE_BENDS_RAD", "ARM_ABDUCTION_RAD"]

KNEE_BENDS_RAD = (0.35, 0.25, 0.45, 0.15, 0.55, 0.0)  # a: hip -a, knee 2a, ankle -a (OP3's stand is 0.35; 0: straight legs, Poppy's)
ARM_ABDUCTION_RAD = 0.25  # arms this far out from the body: clear of the torso and legs
KNEE_LOCK_INSIDE_RAD = 0.005  # a locked knee's goal this far inside its stop (the servo pushes onto it)
COM_MARGIN_M = 0.005  # centre of mass at least this far inside the support polygon


@dataclass(frozen=True)
class StandCandidate:
    qpos: np.ndarray  # robot-alone qpos: root (7) then joints in model order
    knee_bend_rad: float
    lean_rad: float
    com_margin_m: float  # distance of the CoM projection inside the soles' bounding rectangle
    rejected: str = ""  # why it is not statically balanced ('' when it is)

    @property
    def label(self) -> str:
        return f"knees {np.degrees(2 * self.knee_bend_rad):.0f} deg, lean {np.degrees(self.lean_rad):+.1f} deg"


def _role_pose(roles: RoleMap, a: float, t: float) -> dict[str, float]:
    values: dict[str, float] = {}
    for side in ("left", "right"):
        values |= {
            f"{side}.hip_pitch": -a - t,
            f"{side}.knee": 2 * a,
            f"{side}.ankle_pitch": -a + t,
            f"{side}.shoulder_roll": ARM_ABDUCTION_RAD,
        }
    return roles.joint_goals(values)


def _place(m: mujoco.MjModel, d: mujoco.MjData, free_qpos: int, joint_q: dict[int, float], soles: tuple[int, int]) -> None:
    """Set the pose (joints not in ``joint_q`` at ``qpos0``) with the root upright, soles on z = 0."""
    d.qpos[:] = m.qpos0
    for adr, q in joint_q.items():
        d.qpos[adr] = q
    # The root stays upright (no ``flat_sole_xmat``), unlike the adaptation's statics, which turn
    # it to flatten soles that a keyframe tilts: a candidate's leg pitches cancel (hip -a-t, knee
    # 2a, ankle -a+t), so its soles keep the neutral pose's attitude, and the standing keyframe is
    # searched and written with the root upright; turning the root would change every imported
    # robot's stand keyframe (and its digest).
    place_on_soles(m, d, np.arange(free_qpos, free_qpos + 7), soles)


def _com_margin(m: mujoco.MjModel, d: mujoco.MjData, root_body: int, foot_geoms: list[int]) -> tuple[float, float]:
    """CoM x offset from the soles' middle, and its margin inside their bounding rectangle [m]."""
    pts = []
    for g in foot_geoms:
        c, r = d.geom_xpos[g], m.geom_rbound[g]
        if c[2] - r < 0.02:  # geoms that reach the ground
            world = geom_points(m, d, g)
            pts.extend(world[world[:, 2] < 0.01][:, :2])
    com = d.subtree_com[root_body][:2]
    if not pts:
        return 0.0, -1.0
    p = np.array(pts)
    lo, hi = p.min(axis=0), p.max(axis=0)
    mid_x = 0.5 * (lo[0] + hi[0])
    return float(com[0] - mid_x), float(min(com[0] - lo[0], hi[0] - com[0], com[1] - lo[1], hi[1] - com[1]))


def _knee_lock(m: mujoco.MjModel, roles: RoleMap) -> tuple[float, ...]:
    """The bend ``a`` (knee ``2a`` < 0) that rests both knees on their extension stops, if they have
    one past straight: a weak robot stands on locked knees, the stops carry what its servos cannot."""
    bounds = []
    for side in ("left", "right"):
        knee = roles.by_role().get(f"{side}.knee")
        if knee is None:
            return ()
        j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, knee.joint)
        lo, hi = (knee.sign * (float(v) - knee.neutral_rad) for v in m.jnt_range[j])
        bounds.append(min(lo, hi))
    lock = max(bounds) + KNEE_LOCK_INSIDE_RAD
    return (0.5 * lock,) if lock < 0 else ()


def stand_candidates(
    m: mujoco.MjModel, roles: RoleMap, root_body: int, sole_sites: tuple[int, int], foot_bodies: tuple[int, int]
) -> list[StandCandidate]:
    """Standing postures tried, best first; those not statically balanced say why (``rejected``)."""
    d = mujoco.MjData(m)
    free_qpos = int(m.jnt_qposadr[m.body_jntadr[root_body]])
    adr = {m.joint(j).name: int(m.jnt_qposadr[j]) for j in range(m.njnt)}
    neutral = {adr[j.joint]: j.neutral_rad for j in roles.joints}  # an extra joint too: held where its limb hangs
    foot_geoms = [g for foot in foot_bodies for g in subtree_geoms(m, foot)]
    out = []
    for a in (*KNEE_BENDS_RAD, *_knee_lock(m, roles)):

        def com_offset(t: float) -> float:
            q = neutral | {adr[k]: v for k, v in _role_pose(roles, a, t).items()}
            _place(m, d, free_qpos, q, sole_sites)
            return _com_margin(m, d, root_body, foot_geoms)[0]

        try:
            t = brentq(com_offset, -0.4, 0.4, xtol=1e-4)
        except ValueError:
            t = 0.0
        q = neutral | {adr[k]: v for k, v in _role_pose(roles, a, t).items()}
        _place(m, d, free_qpos, q, sole_sites)
        margin = _com_margin(m, d, root_body, foot_geoms)[1]
        lo, hi = m.jnt_range[:, 0], m.jnt_range[:, 1]
        outside = [
            f"{m.joint(j).name} {d.qpos[m.jnt_qposadr[j]]:+.2f} not in [{lo[j]:+.2f}, {hi[j]:+.2f}]"
            for j in range(m.njnt)
            if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE and m.jnt_limited[j]
            and not lo[j] - 1e-9 <= d.qpos[m.jnt_qposadr[j]] <= hi[j] + 1e-9
        ]
        why = ""
        if outside:
            why = "a joint past its limit: " + ", ".join(outside[:3])
        elif margin < COM_MARGIN_M:
            why = f"CoM {1000 * -margin:.0f} mm outside the feet" if margin < 0 else f"CoM only {1000 * margin:.0f} mm inside the feet"
        out.append(StandCandidate(d.qpos.copy(), a, float(t), margin, why))
    return out
