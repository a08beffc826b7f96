"""The stand frame of an imported robot (x forward, y left, z up), whatever axes its file uses.

robot_rise reads a robot's root frame as its stand frame: lying kinds, roles and sites all assume
it. Files use other conventions (Poppy's SolidWorks export: x to the left, y backward), so the
import finds the stand frame from the body itself, at the file's zero pose:
- down is where two limbs reach farthest from the trunk (the legs: an arm or the head reaches
  alone), snapped to the root frame's nearest axis;
- the lateral axis runs between the legs' first joints;
- forward is where the foot goes when the knee straightens from its flexed side (a knee flexes
  one way: the larger side of its range), else where the toes point (the sole's middle ahead of
  the ankle).
Where the root frame is not the stand frame, :func:`reframe_root` puts a new root body in the
stand frame around the file's root (welded, so the body is the same), carrying the floating base.
"""

from __future__ import annotations

from dataclasses import dataclass
from xml.etree import ElementTree

import mujoco
import numpy as np

from robot_rise.errors import ConfigError
from robot_rise.robot_import.roles import jointed_limbs, subtree_geoms, tip_point

__all__ = ["StandFrame", "stand_frame", "reframe_root", "BASE_BODY"]

BASE_BODY = "robot_rise_base"  # the body added in the stand frame when the file's root is not
AXIS_SNAP_COS = 0.9  # an inferred axis this close to one of the root frame's is that axis
KNEE_PROBE_RAD = 0.4  # how far the knee is turned to see which way the foot goes
AXIS_ALIGNED_COS = 0.8  # a joint axis this close to the lateral axis pitches the leg


@dataclass(frozen=True)
class StandFrame:
    """The stand frame's axes in the root frame (columns: forward, left, up) and how they were found."""

    axes: np.ndarray  # (3, 3)
    notes: tuple[str, ...]

    @property
    def is_root_frame(self) -> bool:
        return bool(np.allclose(self.axes, np.eye(3), atol=1e-9))


def _snap(v: np.ndarray) -> np.ndarray:
    v = v / max(float(np.linalg.norm(v)), 1e-12)
    k = int(np.argmax(np.abs(v)))
    if abs(v[k]) >= AXIS_SNAP_COS:
        out = np.zeros(3)
        out[k] = np.sign(v[k])
        return out
    return v


def stand_frame(m: mujoco.MjModel, root_body: int, skip: frozenset[int] = frozenset()) -> StandFrame:
    """The stand frame of the robot at its zero pose.

    Raises:
        ConfigError: fewer than two limbs (no legs to stand on).
    """
    d = mujoco.MjData(m)
    d.qpos[:] = m.qpos0
    mujoco.mj_kinematics(m, d)
    R = d.xmat[root_body].reshape(3, 3)
    origin = d.xpos[root_body]

    def local(p: np.ndarray) -> np.ndarray:
        return R.T @ (p - origin)

    raw, _ = jointed_limbs(m, root_body, skip)
    if len(raw) < 2:
        raise ConfigError(f"the root body {m.body(root_body).name!r} has {len(raw)} jointed limbs: no recognisable legs")
    tips = [local(tip_point(m, d, int(m.jnt_bodyid[_chain_hinges(m, chain, skip)[-1]]))) for chain, _ in raw]
    # down: the signed root axis along which the two farthest-reaching limbs reach farthest
    best = None
    for axis in np.vstack([np.eye(3), -np.eye(3)]):
        reach = sorted((float(t @ axis) for t in tips), reverse=True)
        score = reach[0] + reach[1]
        if best is None or score > best[0]:
            best = (score, axis)
    assert best is not None
    down = best[1]
    legs = sorted(range(len(raw)), key=lambda i: -float(tips[i] @ down))[:2]
    up = -down
    hips = [local(d.xanchor[_chain_hinges(m, raw[i][0], skip)[0]]) for i in legs]
    lateral = hips[0] - hips[1]
    lateral -= (lateral @ up) * up
    if np.linalg.norm(lateral) < 1e-4:
        lateral = (tips[legs[0]] - tips[legs[1]]) - ((tips[legs[0]] - tips[legs[1]]) @ up) * up
    lateral = _snap(lateral)
    forward_axis = np.cross(lateral, up)
    sign, how = _forward_sign(m, d, _chain_hinges(m, raw[legs[0]][0], skip), forward_axis, lateral, R, origin)
    if sign == 0:
        sign, how = (1, "the root frame's (no knee or toes to tell)") if forward_axis @ np.array([1.0, 0, 0]) >= 0 else (-1, "the root frame's")
    forward = _snap(sign * forward_axis)
    left = np.cross(up, forward)
    axes = np.column_stack([forward, left, up])
    notes: tuple[str, ...] = ()
    if not np.allclose(axes, np.eye(3), atol=1e-9):
        names = ("+x", "+y", "+z", "-x", "-y", "-z")

        def name(v: np.ndarray) -> str:
            for k, a in enumerate(np.vstack([np.eye(3), -np.eye(3)])):
                if np.allclose(v, a, atol=1e-6):
                    return names[k]
            return np.array2string(v, precision=2)

        notes = (
            f"stand frame: the file's root frame is not x forward, z up: forward is its {name(forward)} ({how}), "
            f"left {name(left)}, up {name(up)} (where the legs reach); a root body {BASE_BODY!r} in the stand frame carries the floating base",
        )
    return StandFrame(axes, notes)


def _chain_hinges(m: mujoco.MjModel, chain: list[int], skip: frozenset[int]) -> list[int]:
    """The driven hinges along a chain of bodies, root to tip."""
    return [
        j for b in chain for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b])
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE and j not in skip
    ]  # fmt: skip


def _forward_sign(
    m: mujoco.MjModel, d: mujoco.MjData, hinges: list[int], forward: np.ndarray, lateral: np.ndarray, R: np.ndarray, origin: np.ndarray
) -> tuple[int, str]:
    """+1 if ``forward`` (root frame) is the robot's forward, -1 if backward, 0 if the leg (its driven hinges) cannot tell."""
    tip_body = int(m.jnt_bodyid[hinges[-1]])
    # the knee: a middle joint of the leg turning about the lateral axis, with a one-sided range
    top = R.T @ (d.xanchor[hinges[0]] - origin)
    bottom = R.T @ (tip_point(m, d, tip_body) - origin)
    length = max(float(np.linalg.norm(bottom - top)), 1e-9)

    def from_middle(j: int) -> float:  # the knee sits halfway down the leg; the hip and ankle pitch at its ends
        return abs(float(np.linalg.norm(R.T @ (d.xanchor[j] - origin) - top)) / length - 0.5)

    for j in sorted(hinges, key=from_middle):
        axis = R.T @ d.xaxis[j]
        if from_middle(j) > 0.3 or abs(axis @ lateral) < AXIS_ALIGNED_COS or not m.jnt_limited[j]:
            continue
        lo, hi = m.jnt_range[j]
        if abs(hi + lo) < 0.2 * (hi - lo):
            continue  # a symmetric range does not say which way it flexes
        flex = np.sign(hi if hi > -lo else lo)
        before = R.T @ (tip_point(m, d, tip_body) - origin)
        q = d.qpos.copy()
        d.qpos[m.jnt_qposadr[j]] = flex * KNEE_PROBE_RAD
        mujoco.mj_kinematics(m, d)
        after = R.T @ (tip_point(m, d, tip_body) - origin)
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        moved = float((after - before) @ forward)
        if abs(moved) > 1e-4:
            return (-1 if moved > 0 else 1), f"the knee {m.joint(j).name!r} flexes the foot backward"
    geoms = subtree_geoms(m, tip_body)
    if geoms:
        sole = np.mean([R.T @ (d.geom_xpos[g] - origin) for g in geoms], axis=0)
        ankle = R.T @ (d.xanchor[hinges[-1]] - origin)
        ahead = float((sole - ankle) @ forward)
        if abs(ahead) > 0.005:
            return (1 if ahead > 0 else -1), "the toes point forward"
    return 0, ""


def _quat(mat: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(mat).ravel())
    return q


def reframe_root(spec: mujoco.MjSpec, root_name: str, frame: StandFrame) -> tuple[mujoco.MjSpec, np.ndarray]:
    """A spec whose root body (``BASE_BODY``, upright at the file root's place) is in the stand
    frame, the file's root welded inside it; and the quaternion that turns a root orientation of
    the file's into the new root's (``q_new = q_file * q``).

    The free joint moves to the new root; everything else is the file's, so masses, geoms and
    names are unchanged.
    """
    root = ElementTree.fromstring(spec.to_xml())
    world = root.find("worldbody")
    assert world is not None
    body = next((b for b in world.findall("body") if b.get("name") == root_name), None)
    if body is None:
        raise ConfigError(f"the root body {root_name!r} is not at the top of the worldbody")
    free = [c for c in body if c.tag == "freejoint" or (c.tag == "joint" and c.get("type") == "free")]
    for c in free:
        body.remove(c)
    wrapper = ElementTree.Element("body", {"name": BASE_BODY, "pos": body.get("pos", "0 0 0")})
    for c in free:
        wrapper.append(c)
    q_axes = _quat(frame.axes)  # the stand frame in the file root's frame
    inner = _quat(frame.axes.T)  # the file's root in the stand frame
    body.set("pos", "0 0 0")
    for attr in ("quat", "euler", "axisangle", "xyaxes", "zaxis"):
        body.attrib.pop(attr, None)
    body.set("quat", " ".join(f"{v:.12g}" for v in inner))
    index = list(world).index(body)
    world.remove(body)
    wrapper.append(body)
    world.insert(index, wrapper)
    try:
        new = mujoco.MjSpec.from_string(ElementTree.tostring(root, encoding="unicode"))
    except Exception as e:  # pragma: no cover (the spec's own XML)
        raise ConfigError(f"cannot put the root in the stand frame: {e}") from e
    return new, q_axes
