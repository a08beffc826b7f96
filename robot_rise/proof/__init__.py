"""The proof: does a trajectory of servo targets stand on the robot, on every model it may be?

A replay in MuJoCo through the servo model is judged (torque within the envelope, balance,
divergence, ending upright), then under target noise, on every model variant and, for a
composed rise, from the spread of arrivals. One concept per module:

- ``config``: ``ProofConfig``, the proof's standard (margins, tolerances, noise, ensemble).
- ``violations``: torque, balance and divergence windows of a replay.
- ``timeline``: the segment (plan, blend, motion, hold) a time falls in; stretches on the feet.
- ``fall``: why a replay did not end standing.
- ``verdict``: the replay judged, the frozen ``Proof``, and ``execution_permit``.
- ``prediction``: the positions the executor should see (the proof's replay, the variants' spread).
- ``noise``: the nominal model's replays under 1e-6 rad of target noise (no knife-edge proofs).
- ``ensemble``: the replay on every model variant (``robot_rise.sim.variants``), ``check``.
- ``composed``: a rise proven from its parts: cached start proofs and the approach's arrivals.
- ``start_cache``: start proofs kept on disk per robot, scene, motion and code.
- ``robustness``: one replay on a deliberately wrong model (``stands_under``).
"""

from __future__ import annotations

from robot_rise.proof.config import ProofConfig
from robot_rise.proof.composed import (
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
from robot_rise.proof.fall import describe_fall
from robot_rise.proof.start_cache import (
    CACHE_ENV,
    START_PROOF_FORMAT,
    cache_directory,
    load_start_proof,
    save_start_proof,
    start_proof_key,
)
from robot_rise.proof.noise import NOISE_CHECK_KEY, NoiseCheck, NoiseReplay, noise_check, noisy_trajectory, with_noise
from robot_rise.proof.ensemble import (
    COMBINED_VARIANTS_KEY,
    EnsembleReplayer,
    EnsembleResult,
    check,
    proven_combined_variants,
    proven_noise_replays,
    replay_random_variants,
    with_ensemble,
)
from robot_rise.proof.prediction import PREDICTED_KEY, PredictedPositions, expected_positions_of, predicted_positions
from robot_rise.proof.verdict import Permit, Proof, VariantVerdict, execution_permit, prove, scene_digest
from robot_rise.proof.robustness import stands_under
from robot_rise.proof.violations import Violation, find_violations

__all__ = [
    "ProofConfig",
    "ARRIVAL_SETTLE_S",
    "ARRIVAL_SPREAD_STARTS",
    "COMPOSED_KEY",
    "MAX_WHOLE_REPLAYS",
    "TAIL_MAX_STRETCH",
    "Arrival",
    "ComposedProof",
    "RestPose",
    "StartProof",
    "arrival_spread_starts",
    "gravity_angle_rad",
    "prove_composed",
    "prove_start",
    "settled_start",
    "describe_fall",
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
    "COMBINED_VARIANTS_KEY",
    "EnsembleReplayer",
    "EnsembleResult",
    "check",
    "proven_combined_variants",
    "proven_noise_replays",
    "replay_random_variants",
    "with_ensemble",
    "PREDICTED_KEY",
    "PredictedPositions",
    "expected_positions_of",
    "predicted_positions",
    "Permit",
    "Proof",
    "VariantVerdict",
    "execution_permit",
    "prove",
    "scene_digest",
    "stands_under",
    "Violation",
    "find_violations",
]
