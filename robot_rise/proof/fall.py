"""Why a played motion did not end standing: when, in which segment, and the constraint broken."""

from __future__ import annotations

import numpy as np

from robot_rise.proof.timeline import ON_FEET_MIN_S, feet_stretches, segment_at
from robot_rise.proof.violations import Violation
from robot_rise.sampling import classify_lying
from robot_rise.sim.player import Recording
from robot_rise.sim.standing import world_contact
from robot_rise.trajectory import Trajectory

__all__ = ["describe_fall"]


def describe_fall(rec: Recording, trajectory: Trajectory, violations: list[Violation]) -> str:
    """Why a played motion did not end standing: when, in which segment, and the constraint broken.

    "on its feet" = only the feet touch the ground (the judge's condition). Reported: whether and
    when the robot got onto its feet, when it left them, the highest torso reached, and the
    violation (balance = ZMP outside the support polygon, paper 003 eq. 2.13-2.14; divergence =
    a joint that could not follow its target; torque) nearest before that moment.
    """
    if len(rec.t) == 0:
        return "nothing played"
    h = rec.torso_height_m / rec.stand_height_m
    k_hi = int(np.argmax(h))
    stretches = feet_stretches(rec)
    parts: list[str] = []
    t_ref: float
    if not stretches:
        t_ref = float(rec.t[k_hi])
        parts.append(
            f"never on its feet alone for {ON_FEET_MIN_S:.1f} s; highest torso {100 * h[k_hi]:.0f} % of stand height "
            + segment_at(trajectory, t_ref)
            + f"; ended lying {classify_lying(rec.root_pose[-1, 3:])}"
        )
    else:
        first, last = stretches[-1]
        t_ref = float(rec.t[last])
        after = min(last + 1, len(rec.t) - 1)
        touching = [rec.robot_geom_names[g] for g in np.flatnonzero(world_contact(rec)[after])]
        parts.append(
            f"on its feet {segment_at(trajectory, float(rec.t[first]))} until {rec.t[last]:.2f} s (torso tilt then "
            f"{np.degrees(rec.tilt_rad[last]):.0f} deg, highest torso {100 * h[k_hi]:.0f} % of stand height), then "
            + (
                ("touching the world with " + ", ".join(touching) if touching else "in the air (nothing touches)")
                if last + 1 < len(rec.t)
                else "the recording ended"
            )
        )
    t_fail = t_ref if stretches else float(rec.t[-1])  # never on its feet: the whole play counts
    pressed = [(a, b, t) for a, b, t in rec.obstacle_contact_pairs if t <= t_fail + 0.05]
    if pressed:
        parts.append("touched the scene's obstacles: " + ", ".join(f"{a}/{b} from {t:.2f} s" for a, b, t in pressed[:4]))
    before = [v for v in violations if v.t_start_s <= t_fail + 0.05]
    if before:
        # a fall from the feet: the violation just before it; never up: the first thing that went wrong
        v = max(before, key=lambda v: (v.t_end_s, v.kind == "balance")) if stretches else min(before, key=lambda v: v.t_start_s)
        what = {
            "balance": f"ZMP outside the support polygon by {-1000 * v.value:.0f} mm",
            "divergence": f"joints could not follow their targets ({', '.join(v.joints[:4])}, error {v.value:.2f} rad)",
            "torque": f"torque {v.value:.2f} of the envelope ({', '.join(v.joints[:4])})",
        }.get(v.kind, v.describe())
        parts.append(f"{'last' if stretches else 'first'} violation: {what} {segment_at(trajectory, v.t_start_s)} to {v.t_end_s:.2f} s")
    return "; ".join(parts)

