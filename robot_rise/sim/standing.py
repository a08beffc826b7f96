"""The standing judge: does a recording show the robot standing, within the servo envelope?

Standing (issue 4, numbers in ``robot_rise/constants.py``): torso tilt <= 15 deg from vertical,
torso height >= 90 % of the ``stand`` keyframe's, only the feet touch the world (the ground, or
an obstacle stood on such as a low bed: paper 000 section 5.2), all of it held for 2 s with the
velocities settled. The judge reads a :class:`robot_rise.sim.Recording`.
The ZMP margin it reports comes from the recording (:mod:`robot_rise.sim.balance` computes it).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from robot_rise.constants import STAND_HOLD_S, STAND_MAX_TILT_RAD, STAND_MIN_HEIGHT_FRACTION

if TYPE_CHECKING:
    from robot_rise.sim.player import Recording

__all__ = [
    "StandVerdict",
    "judge",
    "standing_mask",
    "supported_on_feet",
    "world_contact",
    "SETTLED_ROOT_SPEED_M_S",
    "SETTLED_ROOT_RATE_RAD_S",
    "SETTLED_JOINT_SPEED_RAD_S",
]

# "Velocities settled" (ours: a standing 0.5 m robot sways by millimetres; these are ~10x that).
SETTLED_ROOT_SPEED_M_S = 0.05  # root linear speed [m/s]
SETTLED_ROOT_RATE_RAD_S = 0.5  # root angular speed [rad/s]
SETTLED_JOINT_SPEED_RAD_S = 0.5  # every joint [rad/s]


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
