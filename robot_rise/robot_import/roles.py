"""Joint roles inferred from a model: limbs from the kinematic tree, roles from the joint axes, signs and neutrals.

The robot stands in its stand frame (x forward, y left, z up; the root frame at zero pose, or the
``stand`` keyframe if the model has one). Limbs are the jointed subtrees of the root body: the two
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

__all__ = ["Limb", "InferredRoles", "infer_roles", "limbs_of", "subtree_geoms"]

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

    kind: str  # "leg", "arm", "head" or "extra"
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


def _hinges(m: mujoco.MjModel, bodies: list[int]) -> list[int]:
    return [j for b in bodies for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b]) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]


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


def _tip_point(m: mujoco.MjModel, d: mujoco.MjData, tip: int) -> np.ndarray:
    """The far end of a limb: the centre of its last jointed body's geoms (the body origin sits at its joint)."""
    geoms = subtree_geoms(m, tip)
    if not geoms:
        return d.xpos[tip].copy()
    return np.mean([d.geom_xpos[g] for g in geoms], axis=0)


def limbs_of(m: mujoco.MjModel, d: mujoco.MjData, root_body: int) -> tuple[list[Limb], list[str]]:
    """The root body's jointed subtrees, classified into legs, arms and head (``d`` at the stand pose)."""
    notes: list[str] = []
    raw: list[tuple[list[int], list[int]]] = []  # (chain bodies, all bodies)
    for child in range(m.nbody):
        if m.body_parentid[child] != root_body or child == root_body:
            continue
        bodies = _subtree(m, child)
        if not _hinges(m, bodies):
            continue
        raw.append((_main_chain(m, bodies), bodies))
    if len(raw) < 2:
        raise ConfigError(f"the root body {m.body(root_body).name!r} has {len(raw)} jointed limbs: no recognisable legs")
    lowest = [_lowest_z(m, d, bodies) for _, bodies in raw]
    order = np.argsort(lowest)
    leg_ids = set(int(i) for i in order[:2])
    root_pos = d.xpos[root_body]
    kinds: dict[int, str] = {i: "leg" for i in leg_ids}
    rest = [i for i in range(len(raw)) if i not in leg_ids]
    anchor = {i: d.xanchor[_hinges(m, raw[i][0])[0]] - root_pos for i in range(len(raw))}
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
        chain_joints = _hinges(m, chain)
        limbs.append(Limb(kind, side, tuple(chain_joints), tuple(bodies), int(m.jnt_bodyid[chain_joints[-1]])))
        off_chain = [j for j in _hinges(m, bodies) if j not in chain_joints]
        if off_chain:
            notes.append(f"{kind} {side}: joints off the main chain held as extra: {', '.join(m.joint(j).name for j in off_chain)}")
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
        return np.array([d.xanchor[j] - a for j in limb.joints] + [_tip_point(m, d, end_body) - a])

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
    sol = min((least_squares(residual, q, bounds=(lo - 1e-9, hi + 1e-9)) for q in starts), key=lambda r: r.cost)
    # rounded: a neutral is a convention for people to read and edit, not a measurement
    return np.round(sol.x, 2) + 0.0, angle0


def infer_roles(m: mujoco.MjModel, qpos_stand: np.ndarray, root_body: int) -> InferredRoles:
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
    limbs, notes = limbs_of(m, d, root_body)
    frame = d.xmat[root_body].reshape(3, 3)  # columns: the stand frame's axes in world
    roles: list[JointRole] = []
    assigned: set[int] = set()
    for limb in limbs:
        axes = [frame.T @ d.xaxis[j] for j in limb.joints]
        kinds = [_axis_kind(a) for a in axes]
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
        neutral, angle0 = _neutral(m, limb, root_body) if limb.kind in ("leg", "arm") else (np.zeros(len(limb.joints)), 0.0)
        if np.any(neutral != 0):
            notes.append(
                f"{limb.side} {limb.kind}: hangs {np.degrees(angle0):.0f} deg from vertical at zero; neutral (hanging) angles "
                + ", ".join(f"{m.joint(j).name}={v:+.4f}" for j, v in zip(limb.joints, neutral))
            )
        for j, role, axis, kind, q0 in zip(limb.joints, names, axes, kinds, neutral):
            assigned.add(j)
            name = m.joint(j).name
            if role == EXTRA:
                roles.append(JointRole(name, EXTRA, 1, 0.0))
                notes.append(f"{name}: {limb.kind} joint with a {kind} axis, no role: held (extra)")
                continue
            full = f"head.{role}" if limb.kind == "head" else f"{limb.side}.{role}"
            ref = _role_axis(role, limb.side, kind if role == "elbow" else {"pan": "yaw", "tilt": "pitch"}.get(role, kind))
            sign = 1 if float(axis @ ref) >= 0 else -1
            roles.append(JointRole(name, full, sign, float(q0)))
    for j in range(m.njnt):
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE and j not in assigned:
            roles.append(JointRole(m.joint(j).name, EXTRA, 1, 0.0))
            notes.append(f"{m.joint(j).name}: not on a limb of the root body: held (extra)")
    order = {m.joint(j).name: j for j in range(m.njnt)}
    roles.sort(key=lambda r: order[r.joint])
    return InferredRoles(RoleMap(tuple(roles)), tuple(limbs), tuple(notes))
