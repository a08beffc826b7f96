"""Collision geometry as the model defines it: which geoms collide, and the shapes MuJoCo collides.

MuJoCo decides two things robot_rise must not guess (``src/engine/engine_collision_driver.c``):

- Which geom pairs can collide (``collision_mask``): geoms on the same weld body never do, nor a
  body and its weld parent (unless the model disables that filter); body pairs named in
  ``<contact><exclude>`` never do; otherwise two geoms collide iff
  ``(contype1 & conaffinity2) || (contype2 & conaffinity1)``; explicit ``<contact><pair>``
  entries always do; a model with contacts disabled has no pair; plane and height-field geoms
  never collide with each other.
- The shape of a mesh geom: its convex hull (``hull_vertices``: the hull MuJoCo builds at compile
  time, ``mesh_graph``, in the geom frame). A geom's mesh vertices are already in the geom frame:
  MuJoCo moves the geom to the mesh's frame when it compiles.

Questions answered exactly on those shapes: the lowest point of a set of geoms
(``lowest_point_z``: primitives analytically, meshes by their hull vertices) and the radius of a
geom about its frame origin (``geom_radius_m``).

Shapes: geom id arrays (G,); a collision mask (ngeom, ngeom); hull vertices (V, 3) [m].
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import mujoco
import numpy as np

__all__ = [
    "collision_mask",
    "colliding_geoms",
    "hull_vertices",
    "mesh_hulls",
    "lowest_point_z",
    "geom_radius_m",
]

_G = mujoco.mjtGeom
_NO_COLLIDER = (int(_G.mjGEOM_PLANE), int(_G.mjGEOM_HFIELD))  # no collision function between these


def collision_mask(m: mujoco.MjModel) -> np.ndarray:
    """Which geom pairs MuJoCo's collision pipeline can turn into contacts.

    The one place robot_rise answers "can these two geoms collide per the model" (rules in the
    module docstring). Geometry and distance do not enter: a True pair may be far apart.

    Returns:
        Symmetric bool array, shape (ngeom, ngeom), False on the diagonal.
    """
    n = int(m.ngeom)
    dis = int(m.opt.disableflags)
    if dis & (int(mujoco.mjtDisableBit.mjDSBL_CONTACT) | int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)):
        return np.zeros((n, n), dtype=bool)
    body = np.asarray(m.geom_bodyid, dtype=np.int64)
    weld = np.asarray(m.body_weldid, dtype=np.int64)[body]
    weld_parent = np.asarray(m.body_weldid)[np.asarray(m.body_parentid)[weld]]
    same_weld = weld[:, None] == weld[None, :]
    parent = np.zeros((n, n), dtype=bool)
    if not dis & int(mujoco.mjtDisableBit.mjDSBL_FILTERPARENT):
        both_moving = (weld[:, None] != 0) & (weld[None, :] != 0)
        parent = both_moving & ((weld[:, None] == weld_parent[None, :]) | (weld[None, :] == weld_parent[:, None]))
    signature = (np.minimum(body[:, None], body[None, :]) << 16) + np.maximum(body[:, None], body[None, :])
    excluded = np.isin(signature, np.asarray(m.exclude_signature, dtype=np.int64))
    ct = np.asarray(m.geom_contype, dtype=np.int64)
    ca = np.asarray(m.geom_conaffinity, dtype=np.int64)
    bitmask = ((ct[:, None] & ca[None, :]) != 0) | ((ct[None, :] & ca[:, None]) != 0)
    mask = bitmask & ~same_weld & ~parent & ~excluded
    g1, g2 = np.asarray(m.pair_geom1, dtype=int), np.asarray(m.pair_geom2, dtype=int)
    mask[g1, g2] = True
    mask[g2, g1] = True
    no_collider = np.isin(np.asarray(m.geom_type), _NO_COLLIDER)
    mask &= ~(no_collider[:, None] & no_collider[None, :])
    np.fill_diagonal(mask, False)
    return mask


def colliding_geoms(mask: np.ndarray, geoms: np.ndarray, against: np.ndarray | None = None) -> np.ndarray:
    """The geoms among ``geoms`` that can collide with one of ``against`` (default: with any geom).

    Args:
        mask: ``collision_mask`` of the model, shape (ngeom, ngeom).
        geoms: candidate geom ids, shape (G,).
        against: geom ids, shape (A,); None for every geom of the model.

    Returns:
        The subset of ``geoms`` in their order, shape (G',).
    """
    geoms = np.asarray(geoms, dtype=int)
    if against is None:
        keep = mask[geoms].any(axis=1)
    else:
        keep = mask[np.ix_(geoms, np.asarray(against, dtype=int))].any(axis=1)
    return geoms[keep]


def hull_vertices(m: mujoco.MjModel, geom: int) -> np.ndarray:
    """Vertices of the convex hull MuJoCo collides for a mesh geom, in the geom frame [m], shape (V, 3).

    The hull is the one MuJoCo computed at compile time (``mesh_graph``); a mesh without one is
    collided through all its vertices, which are then returned.

    Raises:
        ValueError: the geom is not a mesh.
    """
    if int(m.geom_type[geom]) != int(_G.mjGEOM_MESH):
        raise ValueError(f"geom {geom} ({m.geom(geom).name or 'unnamed'}) is not a mesh")
    mesh = int(m.geom_dataid[geom])
    start, count = int(m.mesh_vertadr[mesh]), int(m.mesh_vertnum[mesh])
    vertices = np.asarray(m.mesh_vert[start : start + count], dtype=float)
    graph = int(m.mesh_graphadr[mesh])
    if graph < 0:
        return vertices
    n_hull = int(m.mesh_graph[graph])  # layout: numvert, numface, vert_edgeadr[numvert], vert_globalid[numvert], ...
    return vertices[np.asarray(m.mesh_graph[graph + 2 + n_hull : graph + 2 + 2 * n_hull], dtype=int)]


def mesh_hulls(m: mujoco.MjModel, geoms: np.ndarray) -> dict[int, np.ndarray]:
    """Hull vertices (geom frame, (V, 3) [m]) of every mesh among ``geoms``, by geom id."""
    return {int(g): hull_vertices(m, int(g)) for g in np.asarray(geoms, dtype=int) if int(m.geom_type[g]) == int(_G.mjGEOM_MESH)}


def lowest_point_z(
    m: mujoco.MjModel, d: mujoco.MjData, geoms: np.ndarray, hulls: Mapping[int, np.ndarray] | None = None
) -> float:
    """Lowest world z of the geoms' collision shapes, from ``d.geom_xpos``/``geom_xmat`` [m].

    Exact for spheres, capsules, cylinders, ellipsoids, boxes and meshes (their convex hulls); a
    height field or SDF geom counts by its bounding sphere (lower than the shape: conservative).
    Call after ``mj_kinematics``.

    Args:
        geoms: geom ids, shape (G,).
        hulls: ``mesh_hulls`` of the geoms (computed here when None).

    Returns:
        The lowest z [m]; +inf for no geoms.
    """
    if hulls is None:
        hulls = mesh_hulls(m, geoms)
    low = np.inf
    for g in geoms:
        t = m.geom_type[g]
        pos = d.geom_xpos[g]
        mat = d.geom_xmat[g].reshape(3, 3)
        size = m.geom_size[g]
        if t == _G.mjGEOM_SPHERE:
            z = pos[2] - size[0]
        elif t == _G.mjGEOM_CAPSULE:
            z = pos[2] - abs(mat[2, 2]) * size[1] - size[0]
        elif t == _G.mjGEOM_BOX:
            z = pos[2] - float(np.abs(mat[2, :]) @ size[:3])
        elif t == _G.mjGEOM_CYLINDER:
            z = pos[2] - abs(mat[2, 2]) * size[1] - size[0] * math.sqrt(max(0.0, 1.0 - mat[2, 2] ** 2))
        elif t == _G.mjGEOM_ELLIPSOID:
            z = pos[2] - float(np.linalg.norm(mat[2, :] * size[:3]))
        elif t == _G.mjGEOM_MESH:
            z = pos[2] + float(np.min(hulls[int(g)] @ mat[2, :]))
        else:  # height field, SDF: bounding sphere
            z = pos[2] - m.geom_rbound[g]
        low = min(low, z)
    return float(low)


def geom_radius_m(m: mujoco.MjModel, geom: int, hull: np.ndarray | None = None) -> float:
    """Radius about the geom's frame origin of a sphere containing its collision shape [m].

    A mesh by its hull vertices (``hull``, computed when None); every other type by MuJoCo's
    ``geom_rbound`` (exact for primitives).
    """
    if int(m.geom_type[geom]) == int(_G.mjGEOM_MESH):
        v = hull_vertices(m, geom) if hull is None else hull
        return float(np.sqrt(np.max(np.einsum("ij,ij->i", v, v))))
    return float(m.geom_rbound[geom])
