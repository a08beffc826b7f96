"""Joint roles inferred from a model: limbs from the kinematic tree, roles from the joint axes, signs and neutrals.

The robot stands in its stand frame (x forward, y left, z up; the root frame at zero pose, or the
``stand`` keyframe if the model has one). Limbs are the jointed subtrees hanging from the trunk (the root body and the bodies welded to it): the two
reaching lowest are the legs, the one above the shoulders near the midline is the head, two
lateral ones are the arms; the side is the sign of y. Along a limb, each joint's axis in the stand
frame says whether it pitches (y), rolls (x) or yaws (z); their order down the limb names them
(hip yaw, hip roll, hip pitch, knee, ankle pitch, ankle roll; shoulder pitch, shoulder roll,
elbow; head pan, tilt). The sign maps the axis onto the role frame of :mod:`robot_rise.roles`, the
neutral angle is where the limb hangs straight down. Every inference comes with a note for people;
``robot.toml`` corrects wrong guesses.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from scipy.optimize import least_squares

from robot_rise.errors import ConfigError
from robot_rise.roles import EXTRA, JointRole, RoleMap

__all__ = ["Limb", "InferredRoles", "infer_roles", "jointed_limbs", "limbs_of", "subtree_geoms", "tip_point", "trunk_bodies", "geom_points", "foot_geoms", "sole_down"]

AXIS_ALIGNED_MIN = 0.8  # |cos| of a joint axis with x, y or z to call it roll, pitch or yaw
HANGING_TOLERANCE_RAD = np.radians(15.0)  # a limb this close to straight down at zero has neutral 0
NEUTRAL_REGULARISATION = 0.05  # pull of the zero pose on the hanging-pose fit: move only the joints that must
_FRAME = np.eye(3)  # stand frame axes: x forward, y left, z up

# Role-frame axes (robot_rise.roles): left side; the right side mirrors them (pitch axes stay,
# roll and yaw axes flip).
_PITCH_AXIS = np.array([0.0, 1.0, 0.0])
_ROLL_AXIS_LEFT = np.array([1.0, 0.0, 0.0])  # positive: a limb below moves to +y, away from the midline
_YAW_AXIS_LEFT = np.array([0.0, 0.0, 1.0])  # positive: toes turn to +y, outward
_ELBOW_PITCH_AXIS = np.array([0.0, -1.0, 0.0])  # positive: the forearm swings forward (flexion)
_ELBOW_ROLL_AXIS_LEFT = np.array([-1.0, 0.0, 0.0])  # a sideways elbow: positive moves the hand inward


@dataclass(frozen=True)
class Limb:
    """A jointed subtree of the root body: its kind, side and joints (model joint ids, root to tip)."""

    kind: str  # "leg", "arm", "head", "spine" (joints between the trunk and a chest) or "extra"
    side: str  # "left", "right" or "" (head, extra)
    joints: tuple[int, ...]
    bodies: tuple[int, ...]
    tip: int  # the body of the limb's last joint (a foot, a forearm, the head)


@dataclass(frozen=True)
class InferredRoles:
    roles: RoleMap
    limbs: tuple[Limb, ...]
    notes: tuple[str, ...]


def _subtree(m: mujoco.MjModel, body: int) -> list[int]:
    out = [body]
    for b in range(body + 1, m.nbody):
        if m.body_parentid[b] in out:
            out.append(b)
    return out


def trunk_bodies(m: mujoco.MjModel, root_body: int) -> set[int]:
    """The root body and the bodies welded to it (no joint between): a torso frame, a dummy base
    link, camera and IMU frames. The limbs hang from these."""
    trunk = {root_body}
    for b in range(root_body + 1, m.nbody):
        if int(m.body_parentid[b]) in trunk and m.body_jntnum[b] == 0:
            trunk.add(b)
    return trunk


def _branches(m: mujoco.MjModel, body: int, skip: frozenset[int] = frozenset()) -> list[int]:
    """Children of ``body`` whose subtrees carry driven hinges."""
    return [c for c in range(body + 1, m.nbody) if m.body_parentid[c] == body and _hinges(m, _subtree(m, c), skip)]


def _spine(m: mujoco.MjModel, first: int, skip: frozenset[int] = frozenset()) -> tuple[list[int], int]:
    """A spine: a chain of bodies from ``first`` to a body two or more limbs branch from (a chest
    carrying arms and head above a waist). ([], -1) if ``first`` starts a plain limb.

    A branch counts as a limb when it has two or more hinges (fingers or toes of one hinge each
    do not make a hand or a foot a chest)."""
    chain = [first]
    current = first
    while True:
        branches = _branches(m, current, skip)
        limbs = [c for c in branches if len(_hinges(m, _subtree(m, c), skip)) >= 2]
        if len(limbs) >= 2:
            return chain, current
        if len(branches) != 1:
            return [], -1
        current = branches[0]
        chain.append(current)


def _main_chain(m: mujoco.MjModel, bodies: list[int]) -> list[int]:
    """Bodies on the path from the limb's first body to its deepest descendant (the longest chain)."""
    depth = {bodies[0]: 0}
    for b in bodies[1:]:
        depth[b] = depth[int(m.body_parentid[b])] + 1
    tip = max(bodies, key=lambda b: (depth[b], -b))
    chain = [tip]
    while chain[-1] != bodies[0]:
        chain.append(int(m.body_parentid[chain[-1]]))
    return chain[::-1]


def _hinges(m: mujoco.MjModel, bodies: list[int], skip: frozenset[int] = frozenset()) -> list[int]:
    """The hinges of ``bodies``, but those in ``skip`` (passive joints a linkage moves)."""
    return [
        j for b in bodies for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b])
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE and j not in skip
    ]  # fmt: skip


def _lowest_z(m: mujoco.MjModel, d: mujoco.MjData, bodies: list[int]) -> float:
    z = [d.xpos[b][2] for b in bodies]
    for g in range(m.ngeom):
        if m.geom_bodyid[g] in bodies:
            z.append(d.geom_xpos[g][2] - m.geom_rbound[g])
    return float(min(z))


def subtree_geoms(m: mujoco.MjModel, body: int) -> list[int]:
    """Geoms of a body and its descendants (a foot with its cleats)."""
    bodies = set(_subtree(m, body))
    return [g for g in range(m.ngeom) if int(m.geom_bodyid[g]) in bodies]


def tip_point(m: mujoco.MjModel, d: mujoco.MjData, tip: int) -> np.ndarray:
    """The far end of a limb: the centre of its last jointed body's geoms (the body origin sits at its joint)."""
    geoms = subtree_geoms(m, tip)
    if not geoms:
        return d.xpos[tip].copy()
    return np.mean([d.geom_xpos[g] for g in geoms], axis=0)


def jointed_limbs(
    m: mujoco.MjModel, root_body: int, skip: frozenset[int] = frozenset()
) -> tuple[list[tuple[list[int], list[int]]], list[tuple[list[int], int]]]:
    """The limbs hanging from the trunk, unclassified, and the spines passed through to reach them.

    Returns:
        (main chain bodies, all bodies) per limb; (spine bodies, the body its limbs branch from) per spine.
    """
    raw: list[tuple[list[int], list[int]]] = []
    spines: list[tuple[list[int], int]] = []
    trunk = trunk_bodies(m, root_body)
    pending = [c for c in range(m.nbody) if m.body_parentid[c] in trunk and c not in trunk]
    while pending:
        child = pending.pop(0)
        bodies = _subtree(m, child)
        if not _hinges(m, bodies, skip):
            continue
        spine, branch = _spine(m, child, skip)
        if spine:
            spines.append((spine, branch))
            pending += _branches(m, branch, skip)
            continue
        raw.append((_main_chain(m, bodies), bodies))
    return raw, spines


def limbs_of(m: mujoco.MjModel, d: mujoco.MjData, root_body: int, skip: frozenset[int] = frozenset()) -> tuple[list[Limb], list[str]]:
    """The jointed subtrees hanging from the trunk (:func:`trunk_bodies`), classified into legs, arms and head (``d`` at the stand pose)."""
    notes: list[str] = []
    raw, spines = jointed_limbs(m, root_body, skip)
    if len(raw) < 2:
        raise ConfigError(f"the root body {m.body(root_body).name!r} has {len(raw)} jointed limbs: no recognisable legs")
    lowest = [_lowest_z(m, d, bodies) for _, bodies in raw]
    order = np.argsort(lowest)
    leg_ids = set(int(i) for i in order[:2])
    root_pos = d.xpos[root_body]
    kinds: dict[int, str] = {i: "leg" for i in leg_ids}
    rest = [i for i in range(len(raw)) if i not in leg_ids]
    root_frame = d.xmat[root_body].reshape(3, 3)  # the stand frame's axes (columns) in world
    anchor = {i: root_frame.T @ (d.xanchor[_hinges(m, raw[i][0], skip)[0]] - root_pos) for i in range(len(raw))}
    # arms: the two most lateral of the rest, on opposite sides; head: the highest near the midline
    lateral = sorted(rest, key=lambda i: -abs(anchor[i][1]))
    arms = [i for i in lateral if abs(anchor[i][1]) > 0.02][:2]
    if len(arms) == 2 and np.sign(anchor[arms[0]][1]) != np.sign(anchor[arms[1]][1]):
        kinds.update({i: "arm" for i in arms})
    others = [i for i in rest if i not in kinds]
    if others:
        head = max(others, key=lambda i: anchor[i][2])
        if abs(anchor[head][1]) < 0.03:
            kinds[head] = "head"
    limbs = []
    for i, (chain, bodies) in enumerate(raw):
        kind = kinds.get(i, "extra")
        side = ("left" if anchor[i][1] > 0 else "right") if kind in ("leg", "arm") else ""
        chain_joints = _hinges(m, chain, skip)
        limbs.append(Limb(kind, side, tuple(chain_joints), tuple(bodies), int(m.jnt_bodyid[chain_joints[-1]])))
        off_chain = [j for j in _hinges(m, bodies, skip) if j not in chain_joints]
        if off_chain:
            notes.append(f"{kind} {side}: joints off the main chain held as extra: {', '.join(m.joint(j).name for j in off_chain)}")
    for spine, branch in spines:
        joints = _hinges(m, spine, skip)
        limbs.append(Limb("spine", "", tuple(joints), tuple(spine), branch))
        notes.append(f"spine: {len(joints)} joints between the trunk and {m.body(branch).name!r} (where {len(_branches(m, branch, skip))} limbs branch)")
    legs = [lb for lb in limbs if lb.kind == "leg"]
    if len(legs) != 2 or legs[0].side == legs[1].side:
        raise ConfigError("no recognisable legs: the two lowest limbs are not a left and a right one")
    return limbs, notes


def _axis_kind(axis: np.ndarray) -> str:
    k = int(np.argmax(np.abs(axis)))
    if abs(axis[k]) < AXIS_ALIGNED_MIN:
        return "oblique"
    return ("roll", "pitch", "yaw")[k]


def _leg_roles(kinds: list[str]) -> list[str]:
    """Role per leg joint from its axis kind, in order from the hip: yaw, roll, pitch, knee, pitch, roll."""
    roles = [EXTRA] * len(kinds)
    pitches = [i for i, k in enumerate(kinds) if k == "pitch"]
    if len(pitches) >= 3:
        roles[pitches[0]], roles[pitches[1]], roles[pitches[-1]] = "hip_pitch", "knee", "ankle_pitch"
    elif len(pitches) == 2:
        roles[pitches[0]], roles[pitches[1]] = "hip_pitch", "knee"
    knee = roles.index("knee") if "knee" in roles else len(kinds)
    rolls = [i for i, k in enumerate(kinds) if k == "roll"]
    hip_rolls = [i for i in rolls if i < knee]
    ankle_rolls = [i for i in rolls if i > knee]
    if hip_rolls:
        roles[hip_rolls[0]] = "hip_roll"
    if ankle_rolls:
        roles[ankle_rolls[-1]] = "ankle_roll"
    yaws = [i for i, k in enumerate(kinds) if k == "yaw" and i < knee]
    if yaws:
        roles[yaws[0]] = "hip_yaw"
    return roles


def _arm_roles(kinds: list[str]) -> list[str]:
    """Role per arm joint: the first pitch is the shoulder pitch, a roll before the last joint the
    shoulder roll, the last joint the elbow."""
    roles = [EXTRA] * len(kinds)
    if len(kinds) >= 2:
        roles[-1] = "elbow"
    if kinds and kinds[0] == "pitch":
        roles[0] = "shoulder_pitch"
    rolls = [i for i, k in enumerate(kinds[:-1]) if k == "roll"]
    if rolls:
        roles[rolls[0]] = "shoulder_roll"
    if len(kinds) == 1 and kinds[0] == "pitch":
        roles[0] = "shoulder_pitch"
    return roles


def _role_axis(role: str, side: str, kind: str) -> np.ndarray:
    mirror = np.array([-1.0, 1.0, -1.0]) if side == "right" else np.ones(3)  # mirrored roll and yaw axes
    if role == "elbow":
        if kind == "pitch":
            return _ELBOW_PITCH_AXIS
        return (_ELBOW_ROLL_AXIS_LEFT if kind == "roll" else _YAW_AXIS_LEFT) * mirror
    if kind == "pitch":
        return _PITCH_AXIS
    return (_ROLL_AXIS_LEFT if kind == "roll" else _YAW_AXIS_LEFT) * mirror


def _neutral(m: mujoco.MjModel, limb: Limb, root_body: int) -> tuple[np.ndarray, float]:
    """Joint angles where the limb hangs straight down (zero unless the zero pose is far from it), and the zero pose's angle from vertical."""
    d = mujoco.MjData(m)
    d.qpos[:] = m.qpos0
    adr = m.body_jntadr[root_body]
    if adr >= 0 and m.jnt_type[adr] == mujoco.mjtJoint.mjJNT_FREE:
        d.qpos[m.jnt_qposadr[adr] + 3 : m.jnt_qposadr[adr] + 7] = [1, 0, 0, 0]
    qadr = np.array([m.jnt_qposadr[j] for j in limb.joints])
    end_body = limb.tip
    first_anchor_joint = limb.joints[0]

    def points(q: np.ndarray) -> np.ndarray:
        """The limb's joint anchors and its tip (the segments between them), relative to the first anchor."""
        d.qpos[qadr] = q
        mujoco.mj_kinematics(m, d)
        a = d.xanchor[first_anchor_joint]
        return np.array([d.xanchor[j] - a for j in limb.joints] + [tip_point(m, d, end_body) - a])

    def tip_angle(q: np.ndarray) -> float:
        v = points(q)[-1]
        return float(np.arccos(np.clip(-v[2] / max(np.linalg.norm(v), 1e-9), -1.0, 1.0)))

    angle0 = tip_angle(np.zeros(len(qadr)))
    if angle0 <= HANGING_TOLERANCE_RAD:
        return np.zeros(len(qadr)), angle0
    lo = np.array([m.jnt_range[j, 0] if m.jnt_limited[j] else -np.pi for j in limb.joints])
    hi = np.array([m.jnt_range[j, 1] if m.jnt_limited[j] else np.pi for j in limb.joints])

    def residual(q: np.ndarray) -> np.ndarray:
        # every segment's horizontal extent, so long segments (upper arm, forearm) count most
        pts = points(q)
        segments = np.diff(pts, axis=0)
        scale = max(float(np.sum(np.linalg.norm(segments, axis=1))), 1e-9)
        return np.concatenate([(segments[:, :2] / scale).ravel(), NEUTRAL_REGULARISATION * q])

    # the zero pose is a saddle (a horizontal limb's height changes as cos): start from each joint
    # turned a quarter turn either way and keep the best fit
    starts = [np.zeros(len(qadr))]
    for k in range(len(qadr)):
        for turn in (-np.pi / 2, np.pi / 2):
            q = np.zeros(len(qadr))
            q[k] = turn
            starts.append(np.clip(q, lo, hi))
    fits = [least_squares(residual, q, bounds=(lo - 1e-9, hi + 1e-9)) for q in starts]
    # straight up has no horizontal extent either: a fit whose tip points up is not hanging
    hanging = [f for f in fits if points(f.x)[-1][2] < 0] or fits
    sol = min(hanging, key=lambda r: r.cost)
    # rounded: a neutral is a convention for people to read and edit, not a measurement
    return np.clip(np.round(sol.x, 2), lo, hi) + 0.0, angle0  # rounded, yet inside the range


SOLE_CONTACT_TOLERANCE_M = 0.002  # foot points this close to the lowest one touch the ground
SOLE_SEARCH_RAD = 0.7  # the flat sole is looked for this far from the zero pose's down
SOLE_FLAT_RAD = np.radians(2.0)  # a sole tilted less than this at the neutral pose is flat


_BOX_CORNERS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)


def geom_points(m: mujoco.MjModel, d: mujoco.MjData, g: int) -> np.ndarray:
    """Points that outline a geom in the world (kinematics in ``d``), shape (k, 3): a mesh's
    vertices (its bounding box can be turned from its faces), else its bounding box's corners."""
    if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
        mesh = int(m.geom_dataid[g])
        verts = m.mesh_vert[m.mesh_vertadr[mesh] : m.mesh_vertadr[mesh] + m.mesh_vertnum[mesh]]
        local = verts[:: max(1, len(verts) // 3000)]
    else:
        local = _BOX_CORNERS * m.geom_aabb[g, 3:] + m.geom_aabb[g, :3]
    return local @ d.geom_xmat[g].reshape(3, 3).T + d.geom_xpos[g]


def foot_geoms(m: mujoco.MjModel, foot: int) -> list[int]:
    """The collision geoms of a foot and what hangs from it (cleats), else all its geoms."""
    return [g for g in subtree_geoms(m, foot) if m.geom_contype[g] or m.geom_conaffinity[g]] or subtree_geoms(m, foot)


def _foot_points(m: mujoco.MjModel, foot: int) -> np.ndarray:
    """Points outlining the foot's collision geoms in the foot body's frame, shape (k, 3)."""
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    R, p = d.xmat[foot].reshape(3, 3), d.xpos[foot]
    pts = [(geom_points(m, d, g) - p) @ R for g in foot_geoms(m, foot)]
    return np.concatenate(pts) if pts else np.zeros((1, 3))


def sole_down(m: mujoco.MjModel, foot: int, down0: np.ndarray) -> np.ndarray:
    """The foot-frame direction that points into the ground when the sole is flat: the one whose
    lowest points span the largest area (a plate, a box, four cleats), searched near ``down0``."""
    from scipy.spatial import ConvexHull, QhullError  # noqa: PLC0415

    pts = _foot_points(m, foot)
    down0 = down0 / np.linalg.norm(down0)
    a = np.cross(down0, [1.0, 0, 0] if abs(down0[0]) < 0.9 else [0, 1.0, 0])
    a /= np.linalg.norm(a)
    b = np.cross(down0, a)
    best = (-1.0, 0.0, down0)
    for u in np.linspace(-SOLE_SEARCH_RAD, SOLE_SEARCH_RAD, 71):
        for v in np.linspace(-SOLE_SEARCH_RAD, SOLE_SEARCH_RAD, 71):
            n = down0 + np.tan(u) * a + np.tan(v) * b
            n /= np.linalg.norm(n)
            h = pts @ n
            low = pts[h > h.max() - SOLE_CONTACT_TOLERANCE_M]
            flat = np.column_stack([low @ a, low @ b])
            try:
                area = ConvexHull(flat).volume if len(low) >= 3 else 0.0
            except QhullError:
                area = 0.0
            tilt = -float(n @ down0)
            if area > best[0] * 1.02 or (area >= best[0] * 0.98 and tilt < best[1]):
                best = (max(area, best[0]), tilt, n)
    return best[2]


def _flatten_sole(m: mujoco.MjModel, limb: Limb, root_body: int, q: np.ndarray, kinds: list[str], knee: int) -> tuple[np.ndarray, float]:
    """The leg's angles ``q`` with the joints below the knee turned so that the sole lies flat
    (root upright), and the sole's tilt before [rad]."""
    ankle = [i for i in range(knee + 1, len(limb.joints)) if kinds[i] in ("pitch", "roll")]
    d = mujoco.MjData(m)
    d.qpos[:] = m.qpos0
    adr = m.body_jntadr[root_body]
    d.qpos[m.jnt_qposadr[adr] + 3 : m.jnt_qposadr[adr] + 7] = [1, 0, 0, 0]
    qadr = np.array([m.jnt_qposadr[j] for j in limb.joints])
    d.qpos[qadr] = q
    mujoco.mj_kinematics(m, d)
    R = d.xmat[limb.tip].reshape(3, 3)
    n = sole_down(m, limb.tip, R.T @ np.array([0.0, 0.0, -1.0]))

    def tilt_vec(x: np.ndarray) -> np.ndarray:
        qq = q.copy()
        qq[ankle] = x
        d.qpos[qadr] = qq
        mujoco.mj_kinematics(m, d)
        return (d.xmat[limb.tip].reshape(3, 3) @ n)[:2]

    before = float(np.arcsin(min(1.0, np.linalg.norm(tilt_vec(q[ankle])))))
    if before < SOLE_FLAT_RAD or not ankle:
        return q, before
    lo = np.array([m.jnt_range[limb.joints[i], 0] for i in ankle])
    hi = np.array([m.jnt_range[limb.joints[i], 1] for i in ankle])
    sol = least_squares(tilt_vec, np.clip(q[ankle], lo, hi), bounds=(lo - 1e-9, hi + 1e-9))
    out = q.copy()
    out[ankle] = np.clip(np.round(sol.x, 2), lo, hi)
    return out, before


def _axes_at(m: mujoco.MjModel, d: mujoco.MjData, limb: Limb, q: np.ndarray, frame: np.ndarray) -> list[np.ndarray]:
    """The limb's joint axes in the stand frame with its joints at ``q`` (``d`` restored after)."""
    qadr = np.array([m.jnt_qposadr[j] for j in limb.joints])
    saved = d.qpos[qadr].copy()
    d.qpos[qadr] = q
    mujoco.mj_kinematics(m, d)
    axes = [frame.T @ d.xaxis[j] for j in limb.joints]
    d.qpos[qadr] = saved
    mujoco.mj_kinematics(m, d)
    return axes


def _arm_score(names: list[str]) -> int:
    """How many of the arm's roles a naming fills (shoulder pitch, shoulder roll, elbow)."""
    return sum(1 for r in ("shoulder_pitch", "shoulder_roll", "elbow") if r in names)


MIRROR_OVERLAP_MIN = 0.5  # a left and a right joint of one role share at least half their range in role terms


def _mirror_disagreements(m: mujoco.MjModel, roles: list[JointRole]) -> list[str]:
    """A note for each role whose left and right ranges, in role terms, barely overlap: the file
    mirrors one side's axis or range wrongly (Poppy's knees: both axes alike, ranges opposite)."""
    by_role = {r.role: r for r in roles if r.role != EXTRA}
    notes = []
    for role, left in by_role.items():
        if not role.startswith("left."):
            continue
        right = by_role.get("right." + role.split(".", 1)[1])
        if right is None:
            continue
        spans = []
        for r in (left, right):
            j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, r.joint)
            a, b = (r.sign * (float(v) - r.neutral_rad) for v in m.jnt_range[j])
            spans.append((min(a, b), max(a, b)))
        overlap = min(spans[0][1], spans[1][1]) - max(spans[0][0], spans[1][0])
        smaller = min(s[1] - s[0] for s in spans)
        if smaller > 0 and overlap < MIRROR_OVERLAP_MIN * smaller:
            notes.append(
                f"{role} and right.{role.split('.', 1)[1]} disagree in role terms: {left.joint} moves [{spans[0][0]:+.2f}, {spans[0][1]:+.2f}], "
                f"{right.joint} [{spans[1][0]:+.2f}, {spans[1][1]:+.2f}]: one side's axis or range in the file is probably mirrored wrongly "
                "(motions use what both allow; correct the file, or the sign in robot.toml)"
            )
    return notes


def infer_roles(m: mujoco.MjModel, qpos_stand: np.ndarray, root_body: int, passive: tuple[str, ...] = ()) -> InferredRoles:
    """Infer every hinge joint's role, sign and neutral angle.

    Args:
        m: the robot alone (a free joint at ``root_body``).
        qpos_stand: the standing posture (qpos of ``m``) whose root frame is the stand frame.
        root_body: body id of the floating base.

    Raises:
        ConfigError: no recognisable legs.
    """
    d = mujoco.MjData(m)
    d.qpos[:] = qpos_stand
    mujoco.mj_kinematics(m, d)
    skip = frozenset(mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in passive)
    limbs, notes = limbs_of(m, d, root_body, skip)
    frame = d.xmat[root_body].reshape(3, 3)  # columns: the stand frame's axes in world
    roles: list[JointRole] = []
    assigned: set[int] = set()
    for limb in limbs:
        neutral, angle0 = _neutral(m, limb, root_body) if limb.kind in ("leg", "arm") else (np.zeros(len(limb.joints)), 0.0)
        axes = [frame.T @ d.xaxis[j] for j in limb.joints]
        kinds = [_axis_kind(a) for a in axes]
        if limb.kind == "arm" and np.any(neutral != 0):
            # an arm held out at zero (a T-pose) names its joints as they turn when it hangs: a
            # joint that swings the arm forward there may twist it about its length here
            hanging = _axes_at(m, d, limb, neutral, frame)
            hanging_kinds = [_axis_kind(a) for a in hanging]
            if hanging_kinds.count("oblique") <= kinds.count("oblique") and _arm_roles(hanging_kinds) != _arm_roles(kinds):
                if _arm_score(_arm_roles(hanging_kinds)) > _arm_score(_arm_roles(kinds)):
                    axes, kinds = hanging, hanging_kinds
                    notes.append(f"{limb.side} arm: joint kinds read where it hangs (it is held out at zero)")
        if limb.kind == "leg":
            names = _leg_roles(kinds)
        elif limb.kind == "arm":
            names = _arm_roles(kinds)
        elif limb.kind == "head":
            names = [EXTRA] * len(kinds)
            yaw = [i for i, k in enumerate(kinds) if k == "yaw"]
            pitch = [i for i, k in enumerate(kinds) if k == "pitch"]
            if yaw:
                names[yaw[0]] = "pan"
            if pitch:
                names[pitch[0]] = "tilt"
        else:
            names = [EXTRA] * len(kinds)
        if limb.kind == "leg" and "knee" in names:
            flat, tilt = _flatten_sole(m, limb, root_body, neutral, kinds, names.index("knee"))
            if np.any(flat != neutral):
                notes.append(
                    f"{limb.side} foot: sole tilted {np.degrees(tilt):.0f} deg at the hanging pose; flat with "
                    + ", ".join(f"{m.joint(j).name}={v:+.2f}" for j, v, w in zip(limb.joints, flat, neutral) if v != w)
                )
                neutral = flat
        if np.any(neutral != 0):
            notes.append(
                f"{limb.side} {limb.kind}: hangs {np.degrees(angle0):.0f} deg from vertical at zero; neutral (hanging) angles "
                + ", ".join(f"{m.joint(j).name}={v:+.4f}" for j, v in zip(limb.joints, neutral))
            )
        for j, role, axis, kind, q0 in zip(limb.joints, names, axes, kinds, neutral):
            assigned.add(j)
            name = m.joint(j).name
            if role == EXTRA:  # its neutral is where the limb hangs: the stand holds it there
                roles.append(JointRole(name, EXTRA, 1, float(q0)))
                notes.append(f"{name}: {limb.kind} joint with a {kind} axis, no role: held (extra)")
                continue
            full = f"head.{role}" if limb.kind == "head" else f"{limb.side}.{role}"
            ref = _role_axis(role, limb.side, kind if role == "elbow" else {"pan": "yaw", "tilt": "pitch"}.get(role, kind))
            sign = 1 if float(axis @ ref) >= 0 else -1
            roles.append(JointRole(name, full, sign, float(q0)))
    for j in range(m.njnt):
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE and j not in assigned and j not in skip:
            roles.append(JointRole(m.joint(j).name, EXTRA, 1, 0.0))
            notes.append(f"{m.joint(j).name}: not on a limb of the root body: held (extra)")
    order = {m.joint(j).name: j for j in range(m.njnt)}
    roles.sort(key=lambda r: order[r.joint])
    notes += _mirror_disagreements(m, roles)
    return InferredRoles(RoleMap(tuple(roles)), tuple(limbs), tuple(notes))
