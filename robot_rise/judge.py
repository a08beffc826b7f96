"""The standing judge and the balance measures (ZMP, support polygon).

Standing (issue 4, numbers in ``robot_rise/constants.py``): torso tilt <= 15 deg from vertical,
torso height >= 90 % of the ``stand`` keyframe's, only the feet touch the ground, all of it held
for 2 s with the velocities settled. The judge reads a :class:`robot_rise.sim.Recording`.

ZMP: paper 003 (Oshita 2003) section 2, eq. (2.11)-(2.12), written there with y up; here z is up:

    ZMP_x = (sum m_i x_i (z''_i + g) - sum m_i (z_i - h) x''_i) / sum m_i (z''_i + g)
    ZMP_y = (sum m_i y_i (z''_i + g) - sum m_i (z_i - h) y''_i) / sum m_i (z''_i + g)

with one point mass per body at its centre of mass and the ground at height h. The support polygon
is the convex hull of the feet's ground contact points; the margin is the signed distance of the
ZMP inside it (paper 003 eq. 2.13-2.14 use the ZMP's position in this polygon for balance).
"""

from __future__ import annotations

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


def convex_hull_2d(points: np.ndarray) -> np.ndarray:
    """Convex hull of 2-D points, counter-clockwise, no repeated end point (monotone chain).

    Args:
        points: shape (P, 2) [m].

    Returns:
        hull vertices, shape (H, 2), H <= P (H < 3 for degenerate input).
    """
    pts = np.unique(np.round(np.asarray(points, dtype=float), 9), axis=0)
    if len(pts) <= 2:
        return pts

    def cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
        return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))

    lower: list[np.ndarray] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list[np.ndarray] = []
    for p in pts[::-1]:
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    L = float(ab @ ab)
    s = 0.0 if L < 1e-18 else float(np.clip((p - a) @ ab / L, 0.0, 1.0))
    return float(np.linalg.norm(p - (a + s * ab)))


def support_margin(point: np.ndarray, contact_points: np.ndarray) -> float:
    """Signed distance of ``point`` inside the convex hull of ``contact_points`` [m].

    Positive inside (distance to the nearest edge), negative outside (minus the distance to the
    polygon). With fewer than 3 hull vertices (a line or point contact) the margin is minus the
    distance to that segment or point (never positive: such a support cannot resist a tilt).

    Args:
        point: (x, y) [m], shape (2,).
        contact_points: shape (P, 2) [m], P >= 1.
    """
    p = np.asarray(point, dtype=float)
    if not np.all(np.isfinite(p)):
        return float("nan")
    hull = convex_hull_2d(contact_points)
    if len(hull) == 1:
        return -float(np.linalg.norm(p - hull[0]))
    if len(hull) == 2:
        return -_segment_distance(p, hull[0], hull[1])
    dists = [_segment_distance(p, hull[i], hull[(i + 1) % len(hull)]) for i in range(len(hull))]
    edge = np.roll(hull, -1, axis=0) - hull
    rel = p - hull
    inside = bool(np.all(edge[:, 0] * rel[:, 1] - edge[:, 1] * rel[:, 0] >= 0))
    return min(dists) if inside else -min(dists)


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


def standing_mask(rec: Recording, *, max_tilt_rad: float = STAND_MAX_TILT_RAD, min_height_fraction: float = STAND_MIN_HEIGHT_FRACTION) -> np.ndarray:
    """Per-sample standing condition (posture, contacts and settled velocities), shape (K,)."""
    posture_ok = (rec.tilt_rad <= max_tilt_rad) & (rec.torso_height_m >= min_height_fraction * rec.stand_height_m) & rec.on_feet
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
        elif not rec.on_feet[last]:
            others = [g for g in rec.touching(last) if rec.robot_geom_names.index(g) not in set(rec.foot_geoms.tolist())]
            reason = f"not only feet on the ground ({', '.join(others) or 'nothing touches'})"
        elif np.isnan(stood_from):
            reason = "not settled at the end"
        else:
            reason = f"stood only {rec.t[-1] - stood_from:.2f} s of {hold_s:.2f} s"
    on = rec.on_feet & np.isfinite(rec.zmp_margin_m)
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
