"""Capsules: exact, vectorised segment-segment distances and the robot's links as capsules.

Paper 004 section 4.1 measures the repulsive energy on the shortest distances between links
approximated by cylinders; paper 000 section 4.2.2 uses sphere-swept volumes. Here every collision
geom becomes one or a few *capsules* (a segment and a radius):

- capsule, cylinder: its own axis and radius;
- sphere: a zero-length capsule;
- box: a few parallel segments along the longest axis, spread over the middle axis, with the
  smallest half-extent as radius; the rounded ends just reach the end faces, so the set lies
  inside the box and misses only its edges and corners (the energy is a guide, validity is
  always decided by ``ValidityChecker``);
- ellipsoid: one capsule along the longest axis with the largest other semi-axis as radius;
- mesh: capsules enclosing the convex hull MuJoCo collides (``robot_rise.geometry``), never
  smaller than it; the hull is cut into convex pieces, one capsule each, until the capsules
  reach at most ``MESH_CAPSULE_MAX_ERROR_M`` beyond the hull or ``MAX_CAPSULES_PER_MESH`` is
  reached (``robot_rise.planning.energy.hull_fit``; the error is measured and reported: ``mesh_fits``);
- anything else (height field, SDF): a sphere of the geom's bounding radius.

Only geoms the model lets collide take part (``robot_rise.geometry.collision_mask``): a visual
geom (contype = conaffinity = 0) is no capsule, and a pair the model filters (same or parent
body, ``<contact><exclude>``, contype/conaffinity) is no pair of the internal term.

Planes (type plane) are not capsules: they are half-spaces (``HalfSpace``) for the external term.

Shapes: a capsule set of K capsules has local endpoints (K, 3) in its body frame, radii (K,).
Everything in metres.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import mujoco
import numpy as np

from robot_rise.geometry import collision_mask, colliding_geoms, hull_vertices
from robot_rise.model import ModelIndex
from robot_rise.planning.energy.hull_fit import MESH_CAPSULE_MAX_ERROR_M, fit_hull_capsules

__all__ = [
    "segment_closest_points",
    "segment_distance",
    "CapsuleSet",
    "HalfSpace",
    "capsules_of_geoms",
    "robot_capsules",
    "world_capsules",
    "ground_halfspaces",
    "non_adjacent_pairs",
    "box_corners",
    "MAX_BOX_SEGMENTS_ROBOT",
    "MAX_BOX_SEGMENTS_WORLD",
]

log = logging.getLogger(__name__)

MAX_BOX_SEGMENTS_ROBOT = 4  # ours: a robot box (torso plate, foot sole) is at most 4 parallel segments
MAX_BOX_SEGMENTS_WORLD = 24  # ours: obstacles (table top, bed) may be wide and flat; more segments
_EPS = 1e-12


def segment_closest_points(
    p0: np.ndarray, p1: np.ndarray, q0: np.ndarray, q1: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact closest points between segments p0-p1 and q0-q1, vectorised over leading axes.

    The clamped-parameter method of Ericson (Real-Time Collision Detection, section 5.1.9),
    written branch-free with ``np.where``; degenerate segments (points) are handled.

    Args:
        p0, p1: endpoints of the first segments [m], shape (..., 3) (broadcast).
        q0, q1: endpoints of the second segments [m], shape (..., 3).

    Returns:
        (distance [m] shape (...,), s shape (...,), t shape (...,)): the closest points are
        p0 + s (p1 - p0) and q0 + t (q1 - q0), with s, t in [0, 1].
    """
    p0, p1, q0, q1 = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (p0, p1, q0, q1)))
    d1 = p1 - p0
    d2 = q1 - q0
    r = p0 - q0
    a = np.einsum("...i,...i->...", d1, d1)
    e = np.einsum("...i,...i->...", d2, d2)
    f = np.einsum("...i,...i->...", d2, r)
    c = np.einsum("...i,...i->...", d1, r)
    b = np.einsum("...i,...i->...", d1, d2)
    a_ok = a > _EPS
    e_ok = e > _EPS
    a_safe = np.where(a_ok, a, 1.0)
    e_safe = np.where(e_ok, e, 1.0)
    denom = a * e - b * b
    # general case: s from the infinite-line solution (0 for parallel lines), clamped
    par = denom <= _EPS * np.maximum(a * e, _EPS)
    s = np.where(par, 0.0, np.clip((b * f - c * e) / np.where(par, 1.0, denom), 0.0, 1.0))
    t = (b * s + f) / e_safe
    # t outside [0, 1]: clamp t and recompute s
    s = np.where(t < 0.0, np.clip(-c / a_safe, 0.0, 1.0), np.where(t > 1.0, np.clip((b - c) / a_safe, 0.0, 1.0), s))
    t = np.clip(t, 0.0, 1.0)
    # degenerate segments
    s = np.where(~a_ok, 0.0, s)
    t = np.where(~a_ok & e_ok, np.clip(f / e_safe, 0.0, 1.0), t)
    s = np.where(a_ok & ~e_ok, np.clip(-c / a_safe, 0.0, 1.0), s)
    t = np.where(~e_ok, 0.0, t)
    cp = p0 + s[..., None] * d1
    cq = q0 + t[..., None] * d2
    dist = np.linalg.norm(cp - cq, axis=-1)
    return dist, s, t


def segment_distance(p0: np.ndarray, p1: np.ndarray, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
    """Shortest distance between segments [m], shape of the broadcast leading axes."""
    return segment_closest_points(p0, p1, q0, q1)[0]


@dataclass(frozen=True)
class CapsuleSet:
    """K capsules attached to bodies of a MuJoCo model.

    Attributes:
        body: body id per capsule, shape (K,).
        geom: geom id the capsule comes from, shape (K,) (a box gives several capsules).
        a_local, b_local: segment endpoints in the body frame [m], shape (K, 3).
        radius: capsule radii [m], shape (K,).
        names: geom name per capsule (diagnostics), length K.
    """

    body: np.ndarray
    geom: np.ndarray
    a_local: np.ndarray
    b_local: np.ndarray
    radius: np.ndarray
    names: tuple[str, ...]

    def __post_init__(self) -> None:
        k = len(self.body)
        if self.a_local.shape != (k, 3) or self.b_local.shape != (k, 3) or self.radius.shape != (k,) or len(self.names) != k:
            raise ValueError("CapsuleSet: body (K,), a_local/b_local (K,3), radius (K,), names K must agree")
        for arr in (self.body, self.geom, self.a_local, self.b_local, self.radius):
            arr.setflags(write=False)

    def __len__(self) -> int:
        return len(self.body)

    def world_endpoints(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """Segment endpoints in the world after ``mj_kinematics`` [m], two arrays (K, 3)."""
        xpos = data.xpos[self.body]
        xmat = data.xmat[self.body].reshape(-1, 3, 3)
        a = xpos + np.einsum("kij,kj->ki", xmat, self.a_local)
        b = xpos + np.einsum("kij,kj->ki", xmat, self.b_local)
        return a, b


@dataclass(frozen=True)
class HalfSpace:
    """The free side of a plane: points x with normal . (x - point) >= 0.

    Attributes:
        point: a point on the plane [m], shape (3,).
        normal: unit normal pointing to the free side, shape (3,).
        name: geom name.
    """

    point: np.ndarray
    normal: np.ndarray
    name: str = ""

    def signed_distance(self, x: np.ndarray) -> np.ndarray:
        """Signed distance of points to the plane [m], x shape (..., 3) -> (...)."""
        return (np.asarray(x) - self.point) @ self.normal



def _geom_capsules(m: mujoco.MjModel, g: int, max_box_segments: int) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """Capsules of one geom in its body frame: list of (a, b, radius)."""
    pos = np.array(m.geom_pos[g])
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, m.geom_quat[g])
    rot = rot.reshape(3, 3)
    size = np.array(m.geom_size[g])
    t = int(m.geom_type[g])  # plain int: numpy ints do not compare with mjtGeom inside tuples
    if t in (int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_CYLINDER)):
        axis = rot[:, 2] * size[1]
        return [(pos - axis, pos + axis, float(size[0]))]
    if t == mujoco.mjtGeom.mjGEOM_SPHERE:
        return [(pos.copy(), pos.copy(), float(size[0]))]
    if t == mujoco.mjtGeom.mjGEOM_BOX:
        order = np.argsort(size[:3])[::-1]  # longest, middle, smallest
        la, lb, lc = size[order]
        ua, ub = rot[:, order[0]], rot[:, order[1]]
        radius = float(lc)
        span = max(lb - lc, 0.0)
        n = 1 if span <= 1e-9 else int(min(max_box_segments, np.ceil(span / max(lc, 1e-9)) + 1))
        offsets = np.array([0.0]) if n == 1 else np.linspace(-span, span, n)
        # segments stop lc short of the end faces, so the rounded ends just reach them
        half = max(la - lc, 0.0)
        return [(pos + o * ub - half * ua, pos + o * ub + half * ua, radius) for o in offsets]
    if t == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
        order = np.argsort(size[:3])[::-1]
        axis = rot[:, order[0]] * max(size[order[0]] - size[order[1]], 0.0)
        return [(pos - axis, pos + axis, float(size[order[1]]))]
    if t == mujoco.mjtGeom.mjGEOM_MESH:
        fit = fit_hull_capsules(hull_vertices(m, g))
        if fit.error_m > MESH_CAPSULE_MAX_ERROR_M:
            log.debug("mesh geom %s: %d capsules reach %.1f mm beyond its hull", m.geom(g).name, len(fit), fit.error_m * 1000)
        return [(pos + rot @ a, pos + rot @ b, float(r)) for a, b, r in zip(fit.a, fit.b, fit.radius)]
    return [(pos.copy(), pos.copy(), float(m.geom_rbound[g]))]


def capsules_of_geoms(m: mujoco.MjModel, geoms: np.ndarray, *, max_box_segments: int) -> CapsuleSet:
    """Capsules of the given geoms (planes are skipped: see ``ground_halfspaces``)."""
    body, geom, a_loc, b_loc, rad, names = [], [], [], [], [], []
    for g in np.asarray(geoms, dtype=int):
        if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE:
            continue
        for a, b, r in _geom_capsules(m, int(g), max_box_segments):
            body.append(int(m.geom_bodyid[g]))
            geom.append(int(g))
            a_loc.append(a)
            b_loc.append(b)
            rad.append(r)
            names.append(m.geom(int(g)).name or f"geom{g}")
    return CapsuleSet(
        body=np.array(body, dtype=int),
        geom=np.array(geom, dtype=int),
        a_local=np.array(a_loc, dtype=float).reshape(-1, 3),
        b_local=np.array(b_loc, dtype=float).reshape(-1, 3),
        radius=np.array(rad, dtype=float),
        names=tuple(names),
    )


def robot_capsules(m: mujoco.MjModel, index: ModelIndex) -> CapsuleSet:
    """The robot's links as capsules (one or more per geom that can collide with anything)."""
    geoms = colliding_geoms(collision_mask(m), index.robot_geoms)
    return capsules_of_geoms(m, geoms, max_box_segments=MAX_BOX_SEGMENTS_ROBOT)


def world_capsules(m: mujoco.MjModel, index: ModelIndex) -> CapsuleSet:
    """Obstacles, and non-plane ground geoms, that can collide with the robot, as capsules (static: body 0, the world)."""
    geoms = np.concatenate([index.obstacle_geoms, index.ground_geoms]).astype(int)
    geoms = colliding_geoms(collision_mask(m), geoms, index.robot_geoms)
    return capsules_of_geoms(m, geoms, max_box_segments=MAX_BOX_SEGMENTS_WORLD)


def ground_halfspaces(m: mujoco.MjModel, index: ModelIndex) -> tuple[HalfSpace, ...]:
    """Plane geoms among the ground and obstacles as half-spaces (their +z side is free)."""
    out = []
    for g in np.concatenate([index.ground_geoms, index.obstacle_geoms]).astype(int):
        if m.geom_type[g] != mujoco.mjtGeom.mjGEOM_PLANE:
            continue
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, m.geom_quat[g])
        normal = rot.reshape(3, 3)[:, 2].copy()
        out.append(HalfSpace(np.array(m.geom_pos[g], dtype=float), normal, m.geom(int(g)).name))
    return tuple(out)


def _geom_parent(m: mujoco.MjModel, body: int, has_geom: set[int]) -> int:
    """Nearest proper ancestor of ``body`` that carries a capsule (0 = world if none)."""
    b = int(m.body_parentid[body])
    while b != 0 and b not in has_geom:
        b = int(m.body_parentid[b])
    return b


def non_adjacent_pairs(m: mujoco.MjModel, caps: CapsuleSet) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (i < j) of capsules on non-neighbouring links (paper 004 eq. 1: l_j not in l_i^nb)
    whose geoms the model lets collide (``robot_rise.geometry.collision_mask``).

    Two links are neighbours when they are on the same body, or one body is the nearest
    capsule-carrying ancestor of the other (bodies without geoms are skipped over, so a torso and
    an upper arm joined through a geom-less shoulder bracket are neighbours). Pairs the model
    filters (contype/conaffinity, ``<contact><exclude>``, weld and parent bodies) are dropped too.

    Returns:
        (i, j) index arrays, shape (P,) each.
    """
    has_geom = {int(b) for b in caps.body}
    parent = {b: _geom_parent(m, b, has_geom) for b in has_geom}
    ii, jj = np.triu_indices(len(caps), k=1)
    bi, bj = caps.body[ii], caps.body[jj]
    collide = collision_mask(m)[caps.geom[ii], caps.geom[jj]]
    keep = np.array(
        [x != y and parent[int(x)] != y and parent[int(y)] != x for x, y in zip(bi, bj)],
        dtype=bool,
    ) & collide
    return ii[keep], jj[keep]


def box_corners(m: mujoco.MjModel, geoms: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The 8 corners of every box among ``geoms``, in their body frames.

    Capsules inside a box miss its corners; against a plane the exact distance of a box is the
    distance of its lowest corner, so the external term uses corners for boxes.

    Returns:
        (body ids (C,), geom ids (C,), corners in the body frame [m] (C, 3)), C = 8 x boxes.
    """
    body, geom, pts = [], [], []
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
    for g in np.asarray(geoms, dtype=int):
        if int(m.geom_type[g]) != int(mujoco.mjtGeom.mjGEOM_BOX):
            continue
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, m.geom_quat[g])
        local = m.geom_pos[g] + (signs * m.geom_size[g]) @ rot.reshape(3, 3).T
        pts.append(local)
        body += [int(m.geom_bodyid[g])] * 8
        geom += [int(g)] * 8
    if not pts:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int), np.zeros((0, 3))
    return np.array(body, dtype=int), np.array(geom, dtype=int), np.concatenate(pts)
