"""The dynamics filter: reshape a planned path + library motion into servo targets that prove.

Paper 000 section 4.3 tracks the smoothed plan in a physics engine and connects it to the
database motion at the most similar frame with blending; here the servo model is the tracking
controller and the filter reshapes the targets, never the physics; the judging is
``robot_rise.proof``. One concept per module:

- ``config``: ``FilterConfig``, the reshaping's tuning (the proof's is ``ProofConfig``).
- ``join``: the plan joined to the library motion with a blend or an overlap; windows of time stretched.
- ``stop``: a failed motion cut short before it goes over the torque bound (goals to where the joints are).
- ``slope``: the flat-ground stance turned to sloped ground (paper 000 section 5.2).
- ``lean``: the lean on arms and feet adapted to a retargeted body (paper 000 section 5.3).
- ``command_limits``: the limits the executor enforces, and targets conformed to them.
- ``loop``: ``dynamics_filter``, iterating reshape and proof.
"""

from __future__ import annotations

from robot_rise.filter.command_limits import (
    COMMAND_LIMITS_KEY,
    CommandLimits,
    LimitsMatch,
    command_limits_for,
    command_limits_of,
    conform,
    match_command_limits,
)
from robot_rise.filter.config import FilterConfig
from robot_rise.filter.stop import STOP_BEFORE_S, STOP_RAMP_S, stopped_before_torque_bound
from robot_rise.filter.join import join_with_blend, join_with_overlap, overlap_of, time_scale
from robot_rise.filter.lean import lean_offsets, shoulder_pitch_joints, torso_pitch_rad
from robot_rise.filter.loop import FilterIteration, FilterResult, dynamics_filter
from robot_rise.filter.slope import (
    SLOPE_MIN_RAD,
    ankle_joints,
    ground_tilt_vector,
    leg_joints,
    slope_ankle_offsets,
    slope_stance_offsets,
)

__all__ = [
    "COMMAND_LIMITS_KEY",
    "CommandLimits",
    "LimitsMatch",
    "command_limits_for",
    "command_limits_of",
    "conform",
    "match_command_limits",
    "FilterConfig",
    "STOP_BEFORE_S",
    "STOP_RAMP_S",
    "stopped_before_torque_bound",
    "join_with_blend",
    "join_with_overlap",
    "overlap_of",
    "time_scale",
    "lean_offsets",
    "shoulder_pitch_joints",
    "torso_pitch_rad",
    "FilterIteration",
    "FilterResult",
    "dynamics_filter",
    "SLOPE_MIN_RAD",
    "ankle_joints",
    "ground_tilt_vector",
    "leg_joints",
    "slope_ankle_offsets",
    "slope_stance_offsets",
]
