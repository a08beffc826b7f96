"""Numbers taken from the papers, in one place, each beside its source.

Paper files live in ``../shared/papers/``: 000 = Lin & Huang 2011 (rising from lying postures),
003 = Oshita 2003 (physics-based animation), 004 = Wang, Ho & Komura 2015 (energy-driven planning).
Numbers of our own choosing that tune these ideas for a 0.5 m robot are marked "ours" with the reason.
"""

from __future__ import annotations

import math

# --- Posture metric, paper 000 section 4.1 eq. (1)-(3), weights from section 5 -------------------
ROOT_ORIENTATION_WEIGHT = 5.0  # w_q in eq. (1): "root = 5" (000 section 5)
METRIC_GROUP_WEIGHTS: dict[str, float] = {
    "head": 0.5,  # 000 section 5: head = 0.5
    "wrist": 0.5,  # 000 section 5: wrist = 0.5
    "hand": 0.3,  # 000 section 5: hand = 0.3
    "foot": 0.7,  # 000 section 5: foot = 0.7
    "toes": 0.1,  # 000 section 5: toes = 0.1
    "default": 1.0,  # 000 section 5: all the other joints = 1
}

# --- RRT-blossom in posture space, paper 000 section 4.2.1 eq. (4)-(5) -----------------------------
BLOSSOM_SPAN_RAD = math.radians(15.0)  # +-15 degrees per DOF around the main direction (000 4.2.1)

# --- Loose-to-strict refinement, paper 000 section 4.2.3 ------------------------------------------
# The paper raises the ground and grows obstacle radii by 0.025 (metres, human scale ~1.7 m) per
# iteration. Ours: the same 0.025 m, which for a 0.51 m robot is a coarser relative step; the
# planner may subdivide it.
LOOSE_TO_STRICT_INCREMENT_M = 0.025

# --- Energy-driven planning, paper 004 ------------------------------------------------------------
GLI_SAFE_ZONE_THRESHOLD = 0.3  # max-abs GLI difference for linear interpolation (004 section 5.2)

# --- Standing judge (robot_rise issue 4; ours: product definition of "standing") -----------------
STAND_MAX_TILT_RAD = math.radians(15.0)
STAND_MIN_HEIGHT_FRACTION = 0.90
STAND_HOLD_S = 2.0
