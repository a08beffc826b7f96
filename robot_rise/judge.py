"""The standing judge and the balance measures (ZMP, support polygon).

Standing (issue 4, numbers in ``robot_rise/constants.py``): torso tilt <= 15 deg from vertical,
torso height >= 90 % of the ``stand`` keyframe's, only the feet touch the world (the ground, or
an obstacle stood on such as a low bed: paper 000 section 5.2), all of it held for 2 s with the
velocities settled. The judge reads a :class:`robot_rise.sim.Recording`.

ZMP: paper 003 (Oshita 2003) section 2, eq. (2.11)-(2.12), written there with y up; here z is up:

    ZMP_x = (sum m_i x_i (z''_i + g) - sum m_i (z_i - h) x''_i) / sum m_i (z''_i + g)
    ZMP_y = (sum m_i y_i (z''_i + g) - sum m_i (z_i - h) y''_i) / sum m_i (z''_i + g)

with one point mass per body at its centre of mass and the ground at height h. The support polygon
is the convex hull of the feet's ground contact points; the margin is the signed distance of the
ZMP inside it (paper 003 eq. 2.13-2.14 use the ZMP's position in this polygon for balance).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from robot_rise.constants import STAND_HOLD_S, STAND_MAX_TILT_RAD, STAND_MIN_HEIGHT_FRACTION

if TYPE_CHECKING:
    from robot_rise.sim import Recording

__all__ = [
    "StandVerdict",
    "judge",
    "zmp_point_mass",
    "supported_on_feet",
    "world_contact",
    "zmp_point_mass_many",
    "support_margin",
    "convex_hull_2d",
    "GRAVITY_M_S2",
    "SETTLED_ROOT_SPEED_M_S",
    "SETTLED_ROOT_RATE_RAD_S",
    "SETTLED_JOINT_SPEED_RAD_S",
]

GRAVITY_M_S2 = 9.81
# "Velocities settled" (ours: a standing 0.5 m robot sways by millimetres; these are ~10x that).
SETTLED_ROOT_SPEED_M_S = 0.05  # root linear speed [m/s]
SETTLED_ROOT_RATE_RAD_S = 0.5  # root angular speed [rad/s]
SETTLED_JOINT_SPEED_RAD_S = 0.5  # every joint [rad/s]


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


@dataclass(frozen=True)
class StandVerdict:
    """The judge's answer for one recording.

    Attributes:
        standing: the robot stood for the whole final hold window.
        reason: why not (empty when standing).
        stood_from_s: start of the final continuous standing stretch [s] (NaN if none).
        final_tilt_rad: torso tilt at the end [rad].
        final_height_fraction: torso height at the end / stand keyframe height.
        peak_envelope_ratio: max torque / envelope ratio over every physics step.
        min_zmp_margin_m: smallest ZMP margin in the support polygon while on feet [m] (NaN if never).
        self_collision: a self contact occurred during the play.
    """

    standing: bool
    reason: str
    stood_from_s: float
    final_tilt_rad: float
    final_height_fraction: float
    peak_envelope_ratio: float
    min_zmp_margin_m: float
    self_collision: bool

    def summary(self) -> str:
        """One line for people."""
        head = "STANDING" if self.standing else f"NOT STANDING ({self.reason})"
        return (
            f"{head}; tilt {np.degrees(self.final_tilt_rad):.1f} deg, height {100 * self.final_height_fraction:.0f} % of stand, "
            f"peak torque/envelope {self.peak_envelope_ratio:.2f}, min ZMP margin {1000 * self.min_zmp_margin_m:.1f} mm, "
            f"self collision {'yes' if self.self_collision else 'no'}"
        )


def world_contact(rec: Recording) -> np.ndarray:
    """Which robot geom rests on the world (the ground or a scene obstacle) per sample, shape (K, G)."""
    if rec.obstacle_touch is None:
        return rec.ground_contact
    return rec.ground_contact | rec.obstacle_touch


def supported_on_feet(rec: Recording) -> np.ndarray:
    """Only the feet touch the world, the ground or an obstacle (standing on a low bed counts;
    lying across a beam with the feet on the floor does not), shape (K,)."""
    world = world_contact(rec)
    others = np.ones(world.shape[1], dtype=bool)
    others[rec.foot_geoms] = False
    return world.any(axis=1) & ~world[:, others].any(axis=1)


def standing_mask(rec: Recording, *, max_tilt_rad: float = STAND_MAX_TILT_RAD, min_height_fraction: float = STAND_MIN_HEIGHT_FRACTION) -> np.ndarray:
    """Per-sample standing condition (posture, contacts and settled velocities), shape (K,)."""
    posture_ok = (rec.tilt_rad <= max_tilt_rad) & (rec.torso_height_m >= min_height_fraction * rec.stand_height_m) & supported_on_feet(rec)
    settled = (
        (np.linalg.norm(rec.root_vel[:, :3], axis=1) <= SETTLED_ROOT_SPEED_M_S)
        & (np.linalg.norm(rec.root_vel[:, 3:], axis=1) <= SETTLED_ROOT_RATE_RAD_S)
        & (np.abs(rec.qd).max(axis=1) <= SETTLED_JOINT_SPEED_RAD_S)
    )
    return posture_ok & settled


def judge(
    rec: Recording,
    *,
    hold_s: float = STAND_HOLD_S,
    max_tilt_rad: float = STAND_MAX_TILT_RAD,
    min_height_fraction: float = STAND_MIN_HEIGHT_FRACTION,
) -> StandVerdict:
    """The standing judge: was the robot standing, settled, for the last ``hold_s`` of ``rec``?

    Args:
        rec: a recording that lasts at least ``hold_s`` beyond the trajectory's end.
        hold_s: how long standing must hold [s].
        max_tilt_rad: torso tilt bound [rad].
        min_height_fraction: torso height bound, fraction of the stand keyframe's.
    """
    ok = standing_mask(rec, max_tilt_rad=max_tilt_rad, min_height_fraction=min_height_fraction)
    K = len(rec.t)
    dt = float(rec.t[1] - rec.t[0]) if K > 1 else 0.0
    # final continuous stretch of True
    j = K
    while j > 0 and ok[j - 1]:
        j -= 1
    stood_from = float(rec.t[j]) - dt if j < K else float("nan")
    held = j < K and (rec.t[-1] - stood_from) >= hold_s - 1e-9
    reason = ""
    if K == 0:
        reason = "empty recording"
    elif not held:
        last = K - 1
        if rec.tilt_rad[last] > max_tilt_rad:
            reason = f"torso tilted {np.degrees(rec.tilt_rad[last]):.0f} deg"
        elif rec.torso_height_m[last] < min_height_fraction * rec.stand_height_m:
            reason = f"torso at {100 * rec.torso_height_m[last] / rec.stand_height_m:.0f} % of stand height"
        elif not supported_on_feet(rec)[last]:
            feet = set(rec.foot_geoms.tolist())
            others = [rec.robot_geom_names[g] for g in np.flatnonzero(world_contact(rec)[last]) if g not in feet]
            reason = f"not only feet on the ground ({', '.join(others) or 'nothing touches'})"
        elif np.isnan(stood_from):
            reason = "not settled at the end"
        else:
            reason = f"stood only {rec.t[-1] - stood_from:.2f} s of {hold_s:.2f} s"
    on = supported_on_feet(rec) & np.isfinite(rec.zmp_margin_m)
    min_margin = float(np.min(rec.zmp_margin_m[on])) if on.any() else float("nan")
    return StandVerdict(
        standing=bool(held),
        reason=reason,
        stood_from_s=stood_from,
        final_tilt_rad=float(rec.tilt_rad[-1]) if K else float("nan"),
        final_height_fraction=float(rec.torso_height_m[-1] / rec.stand_height_m) if K else float("nan"),
        peak_envelope_ratio=float(rec.peak_envelope_ratio),
        min_zmp_margin_m=min_margin,
        self_collision=bool(rec.self_contact.any()),
    )
