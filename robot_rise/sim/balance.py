"""Balance geometry: the ZMP of point masses and the support polygon margin (pure functions).

ZMP: paper 003 (Oshita 2003) section 2, eq. (2.11)-(2.12), written there with y up; here z is up:

    ZMP_x = (sum m_i x_i (z''_i + g) - sum m_i (z_i - h) x''_i) / sum m_i (z''_i + g)
    ZMP_y = (sum m_i y_i (z''_i + g) - sum m_i (z_i - h) y''_i) / sum m_i (z''_i + g)

with one point mass per body at its centre of mass and the ground at height h. The support polygon
is the convex hull of the feet's ground contact points; the margin is the signed distance of the
ZMP inside it (paper 003 eq. 2.13-2.14 use the ZMP's position in this polygon for balance).
"""

from __future__ import annotations

import math

import numpy as np


__all__ = ["zmp_point_mass", "zmp_point_mass_many", "support_margin", "convex_hull_2d", "GRAVITY_M_S2"]

GRAVITY_M_S2 = 9.81


def zmp_point_mass(mass_kg: np.ndarray, com_m: np.ndarray, acc_m_s2: np.ndarray, *, ground_z_m: float = 0.0) -> np.ndarray:
    """ZMP of a set of point masses on horizontal ground (paper 003 eq. 2.11-2.12, z up).

    Args:
        mass_kg: body masses, shape (B,).
        com_m: body centres of mass (world) [m], shape (B, 3).
        acc_m_s2: their linear accelerations, gravity not included [m/s^2], shape (B, 3).
        ground_z_m: ground height h [m].

    Returns:
        ZMP (x, y) on the ground [m], shape (2,). NaN if the masses are in free fall.
    """
    m = np.asarray(mass_kg, dtype=float)
    p = np.asarray(com_m, dtype=float)
    a = np.asarray(acc_m_s2, dtype=float)
    w = m * (a[:, 2] + GRAVITY_M_S2)
    den = float(w.sum())
    if abs(den) < 1e-9:
        return np.array([np.nan, np.nan])
    h = p[:, 2] - ground_z_m
    x = (float(w @ p[:, 0]) - float((m * h) @ a[:, 0])) / den
    y = (float(w @ p[:, 1]) - float((m * h) @ a[:, 1])) / den
    return np.array([x, y])


def zmp_point_mass_many(mass_kg: np.ndarray, com_m: np.ndarray, acc_m_s2: np.ndarray, *, ground_z_m: float = 0.0) -> np.ndarray:
    """:func:`zmp_point_mass` for S samples at once (same formula, vectorised over samples).

    Args:
        mass_kg: body masses, shape (B,).
        com_m: body centres of mass per sample (world) [m], shape (S, B, 3).
        acc_m_s2: their linear accelerations, gravity not included [m/s^2], shape (S, B, 3).
        ground_z_m: ground height h [m].

    Returns:
        ZMP (x, y) per sample [m], shape (S, 2); NaN rows where the masses are in free fall.
    """
    m = np.asarray(mass_kg, dtype=float)
    p = np.asarray(com_m, dtype=float)
    a = np.asarray(acc_m_s2, dtype=float)
    w = m * (a[..., 2] + GRAVITY_M_S2)
    den = w.sum(axis=-1)
    mh = m * (p[..., 2] - ground_z_m)
    out = np.empty(p.shape[:-2] + (2,))
    with np.errstate(divide="ignore", invalid="ignore"):
        for i in range(2):
            out[..., i] = (np.einsum("...b,...b->...", w, p[..., i]) - np.einsum("...b,...b->...", mh, a[..., i])) / den
    out[np.abs(den) < 1e-9] = np.nan
    return out


def _hull_rows(points: np.ndarray) -> list[tuple[float, float]]:
    """Convex hull vertices as Python float pairs (see :func:`convex_hull_2d`).

    Plain Python on the handful of contact points a support polygon has: several times faster
    than numpy on such tiny arrays (the player computes one hull per on-feet sample), with the
    same arithmetic, so the same result.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    try:  # round(x * 1e9) / 1e9 is what np.round(x, 9) computes (scale, round half to even, unscale)
        rows = sorted({(round(x * 1e9) / 1e9, round(y * 1e9) / 1e9) for x, y in pts.tolist()})
    except (OverflowError, ValueError):  # inf or nan
        rows = sorted(set(map(tuple, np.round(pts, 9).tolist())))
    if len(rows) <= 2:
        return rows

    def chain(seq: list[tuple[float, float]]) -> list[tuple[float, float]]:
        out: list[tuple[float, float]] = []
        for b in seq:
            while len(out) >= 2:
                (ox, oy), (ax, ay) = out[-2], out[-1]
                if (ax - ox) * (b[1] - oy) - (ay - oy) * (b[0] - ox) <= 0:  # not a counter-clockwise turn
                    out.pop()
                else:
                    break
            out.append(b)
        return out

    return chain(rows)[:-1] + chain(rows[::-1])[:-1]


def convex_hull_2d(points: np.ndarray) -> np.ndarray:
    """Convex hull of 2-D points, counter-clockwise, no repeated end point (monotone chain).

    Points are rounded to 1e-9 and deduplicated first; the hull starts at the lowest (x, y).

    Args:
        points: shape (P, 2) [m].

    Returns:
        hull vertices, shape (H, 2), H <= P (H < 3 for degenerate input).
    """
    return np.array(_hull_rows(points), dtype=float).reshape(-1, 2)


def _segment_distance(px: float, py: float, a: tuple[float, float], b: tuple[float, float]) -> float:
    """Distance from (px, py) to the segment a-b (a point if a == b)."""
    ax, ay = a
    abx, aby = b[0] - ax, b[1] - ay
    L = abx * abx + aby * aby
    if L < 1e-18:
        s = 0.0
    else:
        s = ((px - ax) * abx + (py - ay) * aby) / L
        s = 0.0 if s < 0.0 else (1.0 if s > 1.0 else s)
    dx, dy = px - (ax + s * abx), py - (ay + s * aby)
    return math.sqrt(dx * dx + dy * dy)


def support_margin(point: np.ndarray, contact_points: np.ndarray) -> float:
    """Signed distance of ``point`` inside the convex hull of ``contact_points`` [m].

    Positive inside (distance to the nearest edge), negative outside (minus the distance to the
    polygon). With fewer than 3 hull vertices (a line or point contact) the margin is minus the
    distance to that segment or point (never positive: such a support cannot resist a tilt).

    Args:
        point: (x, y) [m], shape (2,).
        contact_points: shape (P, 2) [m], P >= 1.
    """
    px, py = np.asarray(point, dtype=float).reshape(2).tolist()
    if not (math.isfinite(px) and math.isfinite(py)):
        return float("nan")
    hull = _hull_rows(contact_points)
    if len(hull) == 1:
        return -_segment_distance(px, py, hull[0], hull[0])
    if len(hull) == 2:
        return -_segment_distance(px, py, hull[0], hull[1])
    dmin = math.inf
    inside = True
    for (ax, ay), (bx, by) in zip(hull, hull[1:] + hull[:1]):  # _segment_distance, inlined
        abx, aby = bx - ax, by - ay
        L = abx * abx + aby * aby
        if L < 1e-18:
            t = 0.0
        else:
            t = ((px - ax) * abx + (py - ay) * aby) / L
            t = 0.0 if t < 0.0 else (1.0 if t > 1.0 else t)
        dx, dy = px - (ax + t * abx), py - (ay + t * aby)
        dist = math.sqrt(dx * dx + dy * dy)
        if dist < dmin:
            dmin = dist
        if abx * (py - ay) - aby * (px - ax) < 0:  # right of a counter-clockwise edge
            inside = False
    return dmin if inside else -dmin
