"""Placing a posture where the robot lies: turned to its facing, at its position, on its floor.

Connecting postures come from library motions recorded elsewhere; before planning, they are
turned about the vertical to the lying robot's facing direction (the yaw that minimises paper
000 eq. 2, as the metric's alignment does), moved to its x, y and rested on the surface it lies
on. When that placement collides with an obstacle, nearby placements are tried.

The same placement predicts where every later frame of the motion would be (:func:`place_like`);
a lying robot cannot move its root by itself, so if the motion has no room there (a table over
it), it cannot rise from here whatever the planner does (:func:`motion_room`).

Two ways of putting a body on the ground, each in one place: a lying body by its lowest point
(:func:`lowest_point_at`: the collision geometry, as the validity checker measures it), a standing
one by its soles (:func:`place_on_soles`: robot-alone kinematics, the sole sites at z = 0).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from robot_rise.posture import Posture, quat_multiply
from robot_rise.validity import ValidityChecker

__all__ = [
    "lowest_point_at",
    "place_on_soles",
    "best_yaw",
    "align_to_start",
    "place_near",
    "PLACEMENT_STEP_M",
    "PLACEMENT_MAX_M",
    "PLACEMENT_LIFTS_M",
    "MotionRoom",
    "place_like",
    "motion_room",
    "ROOM_RADIUS_M",
    "ROOM_LIFTS_M",
    "ROOM_STEP_S",
]

PLACEMENT_STEP_M = 0.05  # rings of candidate placements around the start [m]
PLACEMENT_MAX_M = 0.25
PLACEMENT_LIFTS_M = (0.0, 0.02, 0.04, 0.06, 0.08)  # candidate heights above the start's floor [m]


def lowest_point_at(checker: ValidityChecker, qpos: np.ndarray, z_m: float = 0.0) -> np.ndarray:
    """``qpos`` moved straight up or down so the robot's lowest point is at height ``z_m`` [m].

    Args:
        checker: measures the lowest point (:meth:`ValidityChecker.lowest_point_z`); ``qpos`` is in
            its model's layout.
        qpos: the posture, shape (nq,); not changed.
        z_m: the height the lowest point is put at [m] (0: resting on flat ground).

    Returns:
        a copy of ``qpos`` with only the root height changed, shape (nq,).
    """
    q = np.array(qpos, dtype=float)
    q[checker.index.qpos_root[2]] += z_m - checker.lowest_point_z(q)
    return q


def place_on_soles(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    qpos_root: Sequence[int] | np.ndarray,
    sole_sites: Sequence[int],
    *,
    flat_sole_xmat: np.ndarray | None = None,
) -> None:
    """Stand the posture in ``d`` on its soles: root over the origin, the lowest sole site at z = 0.

    The root is put at the origin, upright, or, with ``flat_sole_xmat``, turned so that the first
    sole site has that orientation (the soles flat, whatever the joints do to them); then it is
    moved vertically until the lowest sole site is at z = 0. ``d`` is left with its kinematics and
    centres of mass computed (``d.site_xpos``, ``d.geom_xpos``, ``d.subtree_com``).

    Args:
        m: a model of the robot alone (no ground needed: nothing is simulated).
        d: its data; ``d.qpos`` holds the joint angles [rad] (the root's 7 values are overwritten).
        qpos_root: the 7 qpos indices of the root free joint (position xyz, quaternion wxyz).
        sole_sites: site ids of the soles.
        flat_sole_xmat: orientation to give the first sole site, shape (3, 3) (its orientation in
            the root frame at a pose where the soles are flat); None keeps the root upright.
    """
    root = np.asarray(qpos_root)
    d.qpos[root] = [0, 0, 0, 1, 0, 0, 0]
    mujoco.mj_kinematics(m, d)
    if flat_sole_xmat is not None:
        sole = d.site_xmat[sole_sites[0]].reshape(3, 3)  # the first sole's frame in the root frame
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, (flat_sole_xmat @ sole.T).ravel())
        d.qpos[root[3:]] = quat
        mujoco.mj_kinematics(m, d)
    d.qpos[root[2]] = -min(d.site_xpos[s][2] for s in sole_sites)
    mujoco.mj_kinematics(m, d)
    mujoco.mj_comPos(m, d)


def best_yaw(q_ref: np.ndarray, q: np.ndarray) -> np.ndarray:
    """R_z(psi) q with psi minimising the orientation distance to q_ref (see posture.py)."""
    k = np.array([0.0, 0.0, 0.0, 1.0])
    a = float(np.dot(q_ref, q))
    b = float(np.dot(q_ref, quat_multiply(k, q)))
    half = math.atan2(b, a)
    rz = np.array([math.cos(half), 0.0, 0.0, math.sin(half)])
    out = quat_multiply(rz, q)
    return out / np.linalg.norm(out)


def align_to_start(goal: Posture, start: Posture, checker: ValidityChecker, *, xy: np.ndarray | None = None) -> Posture:
    """Goal turned to the start's facing direction, at the start's (or given) x, y, resting on z = 0."""
    quat = best_yaw(start.root_quat_wxyz, goal.root_quat_wxyz)
    pos = np.array([*(start.root_pos[:2] if xy is None else xy), 0.0])
    return _lowest_point_at(goal.with_root(pos, quat), checker, 0.0)


def _lowest_point_at(p: Posture, checker: ValidityChecker, z_m: float) -> Posture:
    q = lowest_point_at(checker, checker.qpos_of(p), z_m)
    return p.with_root(q[checker.index.qpos_root[:3]])


def _on_floor(goal: Posture, start: Posture, checker: ValidityChecker, xy: np.ndarray, floor_z: float) -> Posture:
    return _lowest_point_at(align_to_start(goal, start, checker, xy=xy), checker, floor_z)


def _rings() -> list[np.ndarray]:
    out = [np.zeros(2)]
    r = PLACEMENT_STEP_M
    while r <= PLACEMENT_MAX_M + 1e-9:
        for a in np.linspace(0, 2 * np.pi, 8, endpoint=False):
            out.append(r * np.array([np.cos(a), np.sin(a)]))
        r += PLACEMENT_STEP_M
    return out


def place_near(goal: Posture, start: Posture, checker: ValidityChecker) -> Posture:
    """``goal`` placed where ``start`` lies: its facing, its x, y, its lowest point at the start's.

    Resting at the height the robot lies at handles the floor, a bed or a slope under the start.
    If that collides, placements on rings around the start (PLACEMENT_STEP_M up to
    PLACEMENT_MAX_M) and slightly higher (PLACEMENT_LIFTS_M, for something higher under part of
    the body) are tried, nearest first; if none is valid the first is returned and the planner
    reports why it is invalid.
    """
    floor_z = checker.lowest_point_z(checker.qpos_of(start))
    first = _on_floor(goal, start, checker, start.root_pos[:2], floor_z)
    for offset in _rings():
        base = first if not offset.any() else _on_floor(goal, start, checker, start.root_pos[:2] + offset, floor_z)
        for dz in PLACEMENT_LIFTS_M:
            candidate = base.with_root(base.root_pos + np.array([0.0, 0.0, dz]))
            if checker.is_valid(candidate):
                return candidate
    return first


# --- room for the motion: where a motion placed like its connecting posture would go -------------

ROOM_RADIUS_M = 0.10  # the robot may be this far from the predicted place (slip, drift) [m]
ROOM_LIFTS_M = tuple(float(x) for x in np.round(np.arange(-0.04, 0.1201, 0.01), 3))  # heights tried about the start's floor [m]
ROOM_STEP_S = 0.1  # motion frames checked this far apart [s]


@dataclass(frozen=True)
class MotionRoom:
    """Whether a library motion, placed as its connecting posture was, has room in the scene.

    Attributes:
        ok: every checked frame from the connecting frame on has a placement within
            ROOM_RADIUS_M of the predicted one, at some height of ROOM_LIFTS_M about the start's
            floor, that no obstacle intersects (the ground is ignored: under a bed, a beam or on
            a slope the floor may be higher or lower than on the library's flat ground).
        motion: the motion's name.
        blocked_at_s: time after the connecting frame of the first frame without room [s] (None when ok).
        blocked_frame: that frame's index in the motion (-1 when ok).
        xy_m: the predicted root (x, y) at that frame [m].
        obstacles: the obstacle geoms the robot hits there at the predicted place.
        collisions: "robot geom / obstacle geom depth" lines there.
    """

    ok: bool
    motion: str
    blocked_at_s: float | None = None
    blocked_frame: int = -1
    xy_m: tuple[float, float] = (0.0, 0.0)
    obstacles: tuple[str, ...] = ()
    collisions: tuple[str, ...] = ()

    def describe(self) -> str:
        if self.ok:
            return f"{self.motion}: room for the whole motion"
        return (
            f"no room: {self.motion} at {self.blocked_at_s:.2f} s after the connecting frame (frame {self.blocked_frame}, root at "
            f"({self.xy_m[0]:.2f}, {self.xy_m[1]:.2f}) m) collides with {', '.join(self.obstacles)} "
            f"({'; '.join(self.collisions[:4])}) at every placement within {ROOM_RADIUS_M:.2f} m and every height "
            f"{ROOM_LIFTS_M[0]:+.2f}..{ROOM_LIFTS_M[-1]:+.2f} m; a lying robot cannot move its root out from under it first "
            "(no crawling motion in the library)"
        )


def place_like(placed_connect: Posture, library_connect_root: np.ndarray, library_root: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Root pose of a library frame when the connecting frame is placed at ``placed_connect``.

    The placement (place_near) is a turn about the vertical plus a translation; applied to any
    frame of the motion it predicts where that frame would be (as on the library's flat ground).

    Args:
        placed_connect: the connecting posture as placed for planning.
        library_connect_root: the connecting frame's root in the library, [x, y, z, qw, qx, qy, qz].
        library_root: another frame's root in the library, same layout.

    Returns:
        (position [m] shape (3,), quaternion wxyz shape (4,)); z is the library frame's height
        plus the placed connecting posture's height offset.
    """
    lc = np.asarray(library_connect_root, dtype=float)
    lr = np.asarray(library_root, dtype=float)
    inv = lc[3:] * np.array([1.0, -1.0, -1.0, -1.0]) / float(np.dot(lc[3:], lc[3:]))
    rz = quat_multiply(placed_connect.root_quat_wxyz, inv)  # a pure yaw by construction of best_yaw
    yaw = 2.0 * math.atan2(float(rz[3]), float(rz[0]))
    c, s = math.cos(yaw), math.sin(yaw)
    d_xy = np.array([[c, -s], [s, c]]) @ (lr[:2] - lc[:2])
    pos = np.array([*(np.asarray(placed_connect.root_pos[:2]) + d_xy), lr[2] + (placed_connect.root_pos[2] - lc[2])])
    quat = quat_multiply(np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]), lr[3:])
    return pos, quat / np.linalg.norm(quat)


def motion_room(
    motion: str,
    library_root: np.ndarray,
    library_t: np.ndarray,
    library_joints: np.ndarray,
    frame: int,
    placed_connect: Posture,
    obstacle_checker: ValidityChecker,
) -> MotionRoom:
    """Does the motion from ``frame`` on fit among the scene's obstacles where it would go?

    A lying robot has no root actuation: where its motion takes it follows from where it lies. So
    each frame (every ROOM_STEP_S) is placed as :func:`place_like` predicts and checked against the
    obstacles only (``obstacle_checker`` has its ground dropped out of reach), allowing
    ROOM_RADIUS_M of drift and ROOM_LIFTS_M of height (an obstacle under the robot, a bed or a
    beam, is stood on or pushed on, so lifting clears it; one over it, a table, is not cleared).

    Args:
        motion: name, for the report.
        library_root: the motion's root rows [x, y, z, qw, qx, qy, qz], shape (T, 7).
        library_t: its times [s], shape (T,).
        library_joints: its joint rows in the checker's robot joint order [rad], shape (T, n).
        frame: the connecting frame.
        placed_connect: the connecting posture as placed for planning.
        obstacle_checker: a ValidityChecker of the scene whose ground is dropped (Looseness).
    """
    robot = obstacle_checker.robot
    lo, hi = robot.joint_lower, robot.joint_upper
    offsets = [np.zeros(3)] + [
        np.array([ROOM_RADIUS_M * math.cos(a), ROOM_RADIUS_M * math.sin(a), 0.0]) for a in np.linspace(0, 2 * math.pi, 8, endpoint=False)
    ]
    lifts = sorted(ROOM_LIFTS_M, key=abs)
    next_t = float(library_t[frame])
    for k in range(frame, len(library_t)):
        if library_t[k] < next_t - 1e-9 and k != len(library_t) - 1:
            continue
        next_t = float(library_t[k]) + ROOM_STEP_S
        pos, quat = place_like(placed_connect, library_root[frame], library_root[k])
        p = Posture(robot.name, pos, quat, dict(zip(robot.joint_names, np.clip(library_joints[k], lo, hi))))
        q0 = obstacle_checker.qpos_of(p)
        zi = obstacle_checker.index.qpos_root[:3]
        free = False
        for off in offsets:
            for dz in lifts:
                q = q0.copy()
                q[zi] += off + np.array([0.0, 0.0, dz])
                if obstacle_checker.is_valid_qpos(q):
                    free = True
                    break
            if free:
                break
        if free:
            continue
        hits = [c for c in obstacle_checker.check_qpos(q0).collisions if c.kind == "obstacle"]
        if not hits:  # blocked only by self contact of the library's own frame: not the scene's doing
            continue
        names = {obstacle_checker.model.geom(int(g)).name for g in obstacle_checker.index.obstacle_geoms}
        return MotionRoom(
            False, motion, float(library_t[k] - library_t[frame]), k, (float(pos[0]), float(pos[1])),
            tuple(dict.fromkeys(c.geom2 if c.geom2 in names else c.geom1 for c in hits)),
            tuple(f"{c.geom1} / {c.geom2} {-1000 * c.distance_m:.0f} mm" for c in hits),
        )
    return MotionRoom(True, motion)
