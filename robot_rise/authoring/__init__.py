"""Authoring of a robot's get-up motion library: strategies (role keyframes, ``configs/strategies``) adapted, timed, proven and written.

Above the core: only the CLI and tests import this package. Rebuild the library with
``robot-rise library author [--out configs/motions/op3] [--only NAME ...]``.

- :mod:`~robot_rise.authoring.keyframes` -- ``Keyframe``, ``MotionSpec`` and the trajectory
  through the keyframes (PCHIP, rows at ``ROW_HZ``).
- :mod:`~robot_rise.authoring.lying` -- the start posture: a lying posture dropped onto flat
  ground to rest (``settle``, ``quat_lying``).
- :mod:`~robot_rise.authoring.retiming` -- the timing found in MuJoCo against the torque-speed
  envelope (``speed_prescale``, ``subdivide``, ``retime``: the fastest timing and the one before its refinement).
- :mod:`~robot_rise.authoring.goal_lead` -- ``clamp_goal_lead`` for motions that keep their
  timing because they need their momentum (also from the rest states a composed get-up arrives
  in: ``robot_rise.filter.arrival_spread_starts``).
- :mod:`~robot_rise.authoring.robustness` -- the five players a motion must stand on.
- :mod:`~robot_rise.authoring.turn_over` -- ``landing``: where and when a turn-over strategy
  (``"lands"``) leaves the body; ``author_turn_over``: the turn, a planned path and a proven
  get-up written as one motion.
- :mod:`~robot_rise.authoring.write` -- ``motion_specs`` (strategies mapped onto a robot's joints
  by its roles), ``author_library``: settle, time, verify, prove, write;
  ``reprove_library`` proves the shipped motions again (nominal model and ensemble).
"""

from __future__ import annotations

from robot_rise.authoring.goal_lead import LEAD_CLAMP_TARGET, clamp_goal_lead
from robot_rise.authoring.keyframes import ROW_HZ, Keyframe, MotionSpec, build_trajectory
from robot_rise.authoring.lying import quat_lying, settle
from robot_rise.authoring.retiming import RETIME_RATIO_TARGET, Retimed, retime, speed_prescale, subdivide
from robot_rise.authoring.robustness import ROBUST_FRICTION, ROBUST_MASS, TORQUE_BOUND, robustness_players
from robot_rise.authoring.write import PROOF_SCENE, Reproof, author_library, motion_specs, reprove_library, with_proof

__all__ = [
    "LEAD_CLAMP_TARGET",
    "RETIME_RATIO_TARGET",
    "ROBUST_FRICTION",
    "ROBUST_MASS",
    "ROW_HZ",
    "TORQUE_BOUND",
    "Keyframe",
    "MotionSpec",
    "author_library",
    "motion_specs",
    "PROOF_SCENE",
    "Reproof",
    "reprove_library",
    "with_proof",
    "build_trajectory",
    "clamp_goal_lead",
    "quat_lying",
    "Retimed",
    "retime",
    "robustness_players",
    "settle",
    "speed_prescale",
    "subdivide",
]
