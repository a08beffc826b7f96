"""The dynamics filter: turn a planned path + library motion into servo targets proven in MuJoCo.

Paper 000 section 4.3 tracks the smoothed plan in a physics engine and connects it to the
database motion at the most similar frame with blending; here the servo model is the tracking
controller and the filter reshapes the targets, never the physics. One concept per module:

- ``config``: ``FilterConfig``, the filter's tuning.
- ``join``: the plan joined to the library motion with a blend or an overlap; windows of time stretched.
- ``violations``: torque, balance and divergence windows of a replay.
- ``timeline``: the segment (plan, blend, motion, hold) a time falls in; stretches on the feet.
- ``fall``: why a replay did not end standing.
- ``stop``: a failed motion cut short before it goes over the torque bound (goals to where the joints are).
- ``slope``: the flat-ground stance turned to sloped ground (paper 000 section 5.2).
- ``lean``: the lean on arms and feet adapted to a retargeted body (paper 000 section 5.3).
- ``proof``: the replay judged, the frozen ``Proof``, and ``execution_permit``.
- ``command_limits``: the limits the executor enforces, and targets conformed to them.
- ``prediction``: the positions the executor should see (the proof's replay, the variants' spread).
- ``noise``: the nominal model's replays under 1e-6 rad of target noise (no knife-edge proofs).
- ``ensemble``: the replay on every model variant (``robot_rise.sim.variants``), ``check``.
- ``start_cache``: start proofs kept on disk per robot, scene, motion and code.
- ``loop``: ``dynamics_filter``, iterating reshape and proof.
- ``robustness``: one replay on a deliberately wrong model (``stands_under``).
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
from robot_rise.filter.composed import (
    ARRIVAL_SETTLE_S,
    ARRIVAL_SPREAD_STARTS,
    COMPOSED_KEY,
    MAX_WHOLE_REPLAYS,
    TAIL_MAX_STRETCH,
    Arrival,
    ComposedProof,
    RestPose,
    StartProof,
    arrival_spread_starts,
    gravity_angle_rad,
    prove_composed,
    prove_start,
    settled_start,
)
from robot_rise.filter.config import FilterConfig
from robot_rise.filter.fall import describe_fall
from robot_rise.filter.stop import STOP_BEFORE_S, STOP_RAMP_S, stopped_before_torque_bound
from robot_rise.filter.join import join_with_blend, join_with_overlap, overlap_of, time_scale
from robot_rise.filter.lean import lean_offsets, shoulder_pitch_joints, torso_pitch_rad
from robot_rise.filter.loop import FilterIteration, FilterResult, dynamics_filter
from robot_rise.filter.start_cache import (
    CACHE_ENV,
    START_PROOF_FORMAT,
    cache_directory,
    load_start_proof,
    save_start_proof,
    start_proof_key,
)
from robot_rise.filter.noise import NOISE_CHECK_KEY, NoiseCheck, NoiseReplay, noise_check, noisy_trajectory, with_noise
from robot_rise.filter.ensemble import (
    COMBINED_VARIANTS_KEY,
    EnsembleReplayer,
    EnsembleResult,
    check,
    proven_combined_variants,
    proven_noise_replays,
    replay_random_variants,
    with_ensemble,
)
from robot_rise.filter.prediction import PREDICTED_KEY, PredictedPositions, expected_positions_of, predicted_positions
from robot_rise.filter.proof import Permit, Proof, VariantVerdict, execution_permit, prove, scene_digest
from robot_rise.filter.robustness import stands_under
from robot_rise.filter.slope import (
    SLOPE_MIN_RAD,
    ankle_joints,
    ground_tilt_vector,
    leg_joints,
    slope_ankle_offsets,
    slope_stance_offsets,
)
from robot_rise.filter.violations import Violation, find_violations

__all__ = [
    "COMMAND_LIMITS_KEY",
    "CommandLimits",
    "LimitsMatch",
    "command_limits_for",
    "command_limits_of",
    "conform",
    "match_command_limits",
    "PREDICTED_KEY",
    "PredictedPositions",
    "expected_positions_of",
    "predicted_positions",
    "FilterConfig",
    "Violation",
    "FilterIteration",
    "FilterResult",
    "join_with_blend",
    "join_with_overlap",
    "overlap_of",
    "time_scale",
    "find_violations",
    "dynamics_filter",
    "CACHE_ENV",
    "START_PROOF_FORMAT",
    "cache_directory",
    "load_start_proof",
    "save_start_proof",
    "start_proof_key",
    "NOISE_CHECK_KEY",
    "NoiseCheck",
    "NoiseReplay",
    "noise_check",
    "noisy_trajectory",
    "with_noise",
    "Proof",
    "Permit",
    "prove",
    "check",
    "EnsembleReplayer",
    "EnsembleResult",
    "VariantVerdict",
    "replay_random_variants",
    "proven_combined_variants",
    "proven_noise_replays",
    "COMBINED_VARIANTS_KEY",
    "with_ensemble",
    "prove_composed",
    "arrival_spread_starts",
    "ARRIVAL_SPREAD_STARTS",
    "prove_start",
    "settled_start",
    "StartProof",
    "RestPose",
    "ComposedProof",
    "Arrival",
    "ARRIVAL_SETTLE_S",
    "TAIL_MAX_STRETCH",
    "MAX_WHOLE_REPLAYS",
    "COMPOSED_KEY",
    "gravity_angle_rad",
    "execution_permit",
    "scene_digest",
    "stands_under",
    "describe_fall",
    "STOP_BEFORE_S",
    "STOP_RAMP_S",
    "stopped_before_torque_bound",
    "ground_tilt_vector",
    "ankle_joints",
    "slope_ankle_offsets",
    "slope_stance_offsets",
    "leg_joints",
    "SLOPE_MIN_RAD",
    "torso_pitch_rad",
    "shoulder_pitch_joints",
    "lean_offsets",
]
