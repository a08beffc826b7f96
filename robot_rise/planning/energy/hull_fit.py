"""Capsules that contain a mesh's convex hull: the hull cut into convex pieces, one capsule each.

A mesh geom becomes capsules enclosing the convex hull MuJoCo collides (``robot_rise.geometry``),
never smaller than it; the hull is cut until the capsules reach at most
``MESH_CAPSULE_MAX_ERROR_M`` beyond it or ``MAX_CAPSULES_PER_MESH`` is reached
(``fit_hull_capsules``); the error is measured and reported (``mesh_fits``). Metres throughout.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import mujoco
import numpy as np
from scipy.spatial import ConvexHull, QhullError

from robot_rise.geometry import hull_vertices

__all__ = ["HullFit", "fit_hull_capsules", "MeshFit", "mesh_fits", "MESH_CAPSULE_MAX_ERROR_M", "MAX_CAPSULES_PER_MESH"]

# Ours: capsules of a mesh may reach this far beyond its hull (the energy sees the link this much
# early; the validity checker collides the hull itself). A box-like hull needs many capsules for
# less: a capsule's round end stands out of a flat face by up to its radius.
MESH_CAPSULE_MAX_ERROR_M = 0.015
MAX_CAPSULES_PER_MESH = 8  # ours: the internal term's cost grows with the square of the capsule count
_EPS = 1e-12


def _sphere_directions(n: int) -> np.ndarray:
    """n nearly uniform unit vectors (Fibonacci sphere), shape (n, 3)."""
    k = np.arange(n) + 0.5
    polar = np.arccos(1.0 - 2.0 * k / n)
    azimuth = np.pi * (1.0 + 5.0**0.5) * k
    return np.stack([np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)], axis=1)


_SEARCH_DIRECTIONS = _sphere_directions(1024)  # error while fitting
_ERROR_DIRECTIONS = _sphere_directions(4096)  # the reported error (then polished locally)
_RADIUS_FACTORS = np.linspace(1.0, 2.5, 16)  # radii tried per axis, times the smallest enclosing one
_CONTAIN_EPS_M = 1e-9  # radii grow by this: containment survives float rounding
_POLISHED_PER_CAPSULE = 4  # the error's best directions per capsule polished by local search


@dataclass(frozen=True)
class HullFit:
    """Capsules whose union contains a convex hull, in the hull's frame.

    Attributes:
        a, b: segment endpoints [m], shape (k, 3).
        radius: radii [m], shape (k,).
        error_m: the largest distance from a capsule point to the hull [m] (0: inside it): the
            one-sided Hausdorff distance, max over directions n of h_capsule(n) - h_hull(n) for
            the support functions h, over 4096 directions polished locally around each
            capsule's worst few.
    """

    a: np.ndarray
    b: np.ndarray
    radius: np.ndarray
    error_m: float

    def __len__(self) -> int:
        return len(self.radius)


def _excess(directions: np.ndarray, h_hull: np.ndarray, a: np.ndarray, b: np.ndarray, r: np.ndarray) -> np.ndarray:
    """How far each capsule reaches beyond the hull over the directions [m], shape (k,).

    For convex sets, sup over the capsule of the distance to the hull is
    max(0, max_n h_capsule(n) - h_hull(n)); h_capsule(n) = max(n.a, n.b) + r.
    """
    h_cap = np.maximum(directions @ a.T, directions @ b.T) + r
    return np.maximum((h_cap - h_hull[:, None]).max(axis=0), 0.0)


def _refined_excess(hull: np.ndarray, h_hull: np.ndarray, a: np.ndarray, b: np.ndarray, r: np.ndarray) -> float:
    """The error of a capsule set: per capsule, its worst few error directions (``h_hull`` over them), polished locally."""
    gap = np.maximum(_ERROR_DIRECTIONS @ a.T, _ERROR_DIRECTIONS @ b.T) + r - h_hull[:, None]  # (directions, k)
    best = float(gap.max())
    rng = np.random.default_rng(0)
    for c in range(len(r)):
        for k in np.argsort(gap[:, c])[-_POLISHED_PER_CAPSULE:]:
            top, n0 = float(gap[k, c]), _ERROR_DIRECTIONS[k]
            step = 0.05  # rad: about the spacing of the error directions
            for _ in range(12):
                cand = n0 + step * rng.standard_normal((32, 3))
                cand /= np.linalg.norm(cand, axis=1)[:, None]
                e = np.maximum(cand @ a[c], cand @ b[c]) + r[c] - (cand @ hull.T).max(axis=1)
                j = int(np.argmax(e))
                if e[j] > top:
                    top, n0 = float(e[j]), cand[j]
                step *= 0.6
            best = max(best, top)
    return max(best, 0.0)


def _circle_centre(q: np.ndarray) -> np.ndarray:
    """Centre of the smallest circle around 2-D points q (n, 2): Welzl's incremental algorithm on their hull."""
    if len(q) >= 3:
        try:
            q = q[ConvexHull(q).vertices]
        except QhullError:  # collinear or repeated points: all of them
            pass
    q = q[np.random.default_rng(0).permutation(len(q))]
    pts = [tuple(p) for p in q.tolist()]

    def inside(p: tuple[float, float], c: tuple[float, float, float]) -> bool:
        return (p[0] - c[0]) ** 2 + (p[1] - c[1]) ** 2 <= c[2] * (1.0 + 1e-12) + 1e-30

    def two(p: tuple[float, float], s: tuple[float, float]) -> tuple[float, float, float]:
        cx, cy = (p[0] + s[0]) / 2.0, (p[1] + s[1]) / 2.0
        return cx, cy, (p[0] - cx) ** 2 + (p[1] - cy) ** 2

    def three(p: tuple[float, float], s: tuple[float, float], t: tuple[float, float]) -> tuple[float, float, float]:
        ax, ay = s[0] - p[0], s[1] - p[1]
        bx, by = t[0] - p[0], t[1] - p[1]
        det = 2.0 * (ax * by - ay * bx)
        if abs(det) < 1e-300:  # collinear: the widest pair
            return max((two(p, s), two(p, t), two(s, t)), key=lambda c: c[2])
        ux = (by * (ax * ax + ay * ay) - ay * (bx * bx + by * by)) / det
        uy = (ax * (bx * bx + by * by) - bx * (ax * ax + ay * ay)) / det
        return p[0] + ux, p[1] + uy, ux * ux + uy * uy

    c = (pts[0][0], pts[0][1], 0.0)
    for i in range(1, len(pts)):
        if inside(pts[i], c):
            continue
        c = (pts[i][0], pts[i][1], 0.0)
        for j in range(i):
            if inside(pts[j], c):
                continue
            c = two(pts[i], pts[j])
            for k in range(j):
                if not inside(pts[k], c):
                    c = three(pts[i], pts[j], pts[k])
    return np.array(c[:2])


def _principal_axes(x: np.ndarray) -> np.ndarray:
    """Principal axes of centred points x (n, 3), largest spread first, as rows, shape (3, 3)."""
    _, v = np.linalg.eigh(x.T @ x)
    return v[:, ::-1].T


def _piece_capsule(piece: np.ndarray, h_hull: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, float]:
    """The capsule containing a convex piece (its vertices, (n, 3)) that reaches least beyond the hull.

    Axes tried: the piece's principal axes; radii: from the smallest that holds every vertex
    around that axis up to 2.5 times it (a larger radius shortens the segment and so the round
    ends). Returns (a, b, radius, error over the search directions).
    """
    centre = piece.mean(axis=0)
    x = piece - centre
    best: list[tuple[np.ndarray, np.ndarray, float, float]] = []
    for u in _principal_axes(x):
        e1 = np.cross(u, [1.0, 0.0, 0.0] if abs(u[0]) < 0.9 else [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(u, e1)
        t = x @ u
        q = np.stack([x @ e1, x @ e2], axis=1)
        c2 = _circle_centre(q)
        d2 = np.einsum("ij,ij->i", q - c2, q - c2)
        base = centre + c2[0] * e1 + c2[1] * e2
        r = np.sqrt(d2.max()) * _RADIUS_FACTORS + _CONTAIN_EPS_M  # (R,)
        slack = np.sqrt(np.maximum(r[:, None] ** 2 - d2[None, :], 0.0))  # (R, n)
        hi = (t[None, :] - slack).max(axis=1)
        lo = (t[None, :] + slack).min(axis=1)
        ball = lo > hi  # every vertex fits in one sphere: centre it, grow the radius to hold them
        mid = np.where(ball, (lo + hi) / 2.0, 0.0)
        lo, hi = np.where(ball, mid, lo), np.where(ball, mid, hi)
        a = base + lo[:, None] * u
        b = base + hi[:, None] * u
        far = np.sqrt(((piece[None, :, :] - a[:, None, :]) ** 2).sum(axis=2).max(axis=1)) + _CONTAIN_EPS_M
        r = np.where(ball, np.maximum(r, far), r)
        err = _excess(_SEARCH_DIRECTIONS, h_hull, a, b, r)
        i = int(np.argmin(err))
        best.append((a[i], b[i], float(r[i]), float(err[i])))
    return min(best, key=lambda c: c[3])


def _edges(points: np.ndarray) -> np.ndarray:
    """Edges (i, j) of the convex hull of points, shape (E, 2); all pairs when it is flat or tiny.

    All pairs are a superset of the hull's edges whose extra segments lie inside it, so cutting
    them only adds points inside the piece.
    """
    if len(points) >= 4:
        try:
            tri = ConvexHull(points).simplices
            e = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [0, 2]]]), axis=1)
            return np.unique(e, axis=0)
        except QhullError:
            pass
    i, j = np.triu_indices(len(points), k=1)
    return np.stack([i, j], axis=1)


def _cut(points: np.ndarray, normal: np.ndarray, offset: float) -> tuple[np.ndarray, np.ndarray]:
    """A convex piece (its vertices) cut by the plane normal . x = offset: the vertices of both halves."""
    s = points @ normal - offset
    e = _edges(points)
    sa, sb = s[e[:, 0]], s[e[:, 1]]
    crossing = ((sa < 0.0) & (sb > 0.0)) | ((sa > 0.0) & (sb < 0.0))
    e, sa, sb = e[crossing], sa[crossing], sb[crossing]
    w = (sa / (sa - sb))[:, None]
    on_plane = points[e[:, 0]] + w * (points[e[:, 1]] - points[e[:, 0]])
    return np.concatenate([points[s <= 0.0], on_plane]), np.concatenate([points[s >= 0.0], on_plane])


def _fit_hull(hull: np.ndarray, max_error_m: float, max_capsules: int) -> HullFit:
    """Greedy refinement: cut the piece whose capsule reaches farthest; keep the best set seen."""
    h_search = (_SEARCH_DIRECTIONS @ hull.T).max(axis=1)
    h_error = (_ERROR_DIRECTIONS @ hull.T).max(axis=1)
    pieces = [hull]
    caps = [_piece_capsule(hull, h_search)]

    def as_fit(caps: list[tuple[np.ndarray, np.ndarray, float, float]]) -> HullFit:
        a, b, r = (np.array([c[k] for c in caps]) for k in range(3))
        return HullFit(a, b, r, _refined_excess(hull, h_error, a, b, r))

    fits = [as_fit(caps)]
    while fits[-1].error_m > max_error_m and len(caps) < max_capsules:
        i = int(np.argmax([c[3] for c in caps]))
        piece = pieces[i]
        best: tuple[float, list[np.ndarray], list[tuple[np.ndarray, np.ndarray, float, float]]] | None = None
        for u in _principal_axes(piece - piece.mean(axis=0)):
            t = piece @ u
            halves = _cut(piece, u, float(t.max() + t.min()) / 2.0)
            if min(len(h) for h in halves) == 0:
                continue
            two = [_piece_capsule(h, h_search) for h in halves]
            worst = max(c[3] for c in two)
            if best is None or worst < best[0]:
                best = (worst, list(halves), two)
        if best is None:
            break
        pieces[i : i + 1] = best[1]
        caps[i : i + 1] = best[2]
        fits.append(as_fit(caps))
    return fits[-1] if fits[-1].error_m <= max_error_m else min(fits, key=lambda f: (f.error_m, len(f)))


@functools.lru_cache(maxsize=256)
def _fit_cached(key: bytes, n: int, max_error_m: float, max_capsules: int) -> HullFit:
    hull = np.frombuffer(key, dtype=float).reshape(n, 3)
    fit = _fit_hull(hull, max_error_m, max_capsules)
    for arr in (fit.a, fit.b, fit.radius):
        arr.setflags(write=False)
    return fit


def fit_hull_capsules(
    hull: np.ndarray, *, max_error_m: float = MESH_CAPSULE_MAX_ERROR_M, max_capsules: int = MAX_CAPSULES_PER_MESH
) -> HullFit:
    """Capsules whose union contains a convex hull, reaching at most ``max_error_m`` beyond it if they can.

    Every hull vertex lies inside a capsule (so the whole hull does: each capsule holds a convex
    piece of it). The hull is cut in two at the middle of the worst piece's principal axis that
    helps most, one capsule per piece, until the error is within ``max_error_m`` or there are
    ``max_capsules``; then the fewest capsules within the bound, else the smallest error, are
    returned with their error (``HullFit.error_m``). Results are cached per hull.

    Args:
        hull: hull vertices [m], shape (V, 3).
        max_error_m: the error to reach [m].
        max_capsules: at most this many capsules.
    """
    hull = np.ascontiguousarray(hull, dtype=float)
    if hull.ndim != 2 or hull.shape[1] != 3 or len(hull) == 0:
        raise ValueError(f"fit_hull_capsules: hull must be (V, 3) with V > 0, got shape {hull.shape}")
    if max_capsules < 1:
        raise ValueError(f"fit_hull_capsules: max_capsules must be >= 1, got {max_capsules}")
    return _fit_cached(hull.tobytes(), len(hull), float(max_error_m), int(max_capsules))


@dataclass(frozen=True)
class MeshFit:
    """How well the capsules of one mesh geom fit its convex hull.

    Attributes:
        geom: geom id; name: its name.
        capsules: number of capsules.
        error_m: the largest distance from a capsule point to the hull [m].
        within_bound: error_m <= MESH_CAPSULE_MAX_ERROR_M.
    """

    geom: int
    name: str
    capsules: int
    error_m: float
    within_bound: bool

    def describe(self) -> str:
        flag = "" if self.within_bound else f" (over the {MESH_CAPSULE_MAX_ERROR_M * 1000:.0f} mm bound)"
        return f"{self.name}: {self.capsules} capsules, up to {self.error_m * 1000:.1f} mm beyond the hull{flag}"


def mesh_fits(m: mujoco.MjModel, geoms: np.ndarray) -> tuple[MeshFit, ...]:
    """The capsule fit of every mesh among ``geoms`` (the capsule model's error, reported)."""
    out = []
    for g in np.asarray(geoms, dtype=int):
        if int(m.geom_type[g]) != int(mujoco.mjtGeom.mjGEOM_MESH):
            continue
        fit = fit_hull_capsules(hull_vertices(m, int(g)))
        name = m.geom(int(g)).name or f"geom{g}"
        out.append(MeshFit(int(g), name, len(fit), fit.error_m, fit.error_m <= MESH_CAPSULE_MAX_ERROR_M))
    return tuple(out)
