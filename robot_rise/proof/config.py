"""The proof's standard: one frozen ``ProofConfig`` (margins, tolerances, hold, noise, ensemble)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from robot_rise.constants import ENVELOPE_MARGIN, PROOF_HEADROOM, TARGET_NOISE_RAD
from robot_rise.validity import DEFAULT_CONTACT_TOLERANCE_M

__all__ = ["ProofConfig"]


@dataclass(frozen=True)
class ProofConfig:
    """What a replay must hold to be proven, and on which models.

    Attributes:
        envelope_margin: torque may use at most (1 - margin) of the torque-speed envelope
            (issue 6 default 10 %).
        proof_headroom: ``dynamics_filter`` proves within (1 - margin - headroom) of the envelope;
            ``check`` and ``prove`` judge (1 - margin). So a verdict the filter reached keeps under
            ``check``'s fresh target noise (``robot_rise.constants.PROOF_HEADROOM``). Library
            motions' own proofs (authoring, the composed proof's start proofs) judge (1 - margin):
            the shipped ones peak at 0.79-0.85.
        self_penetration_tolerance_m: self contact deeper than this is a collision; shallower
            is touching (the validity checker's tolerance, so planner and filter agree).
        min_zmp_margin_m: the ZMP must stay this far inside the support polygon while on feet [m].
        balance_tolerance_m: ZMP excursions shallower than this are estimation noise (point-mass
            ZMP, support polygon from discrete contact points) [m].
        balance_hold_s: a ZMP excursion counts when it lasts this long [s] (impacts at touchdown
            are instantaneous and not a loss of balance).
        divergence_rad: tracking error counted as divergence [rad] (default 1.5 x the servo's
            saturation error: beyond saturation the servo pushes with all it has).
        divergence_hold_s: how long the error must last to count [s].
        hold_s: time the final targets are held while the judge watches [s].
        ensemble: prove on every model variant too (``robot_rise.sim.variants.ENSEMBLE``).
        combined_variants: with ``ensemble``, also prove on the first this many combined random
            variants (``robot_rise.sim.variants.combined_variants``); ``rise`` sets it per
            candidate from ``robot_rise.library.Motion.combined_variants``.
        noise_replays: the nominal model also replays this many copies of the proven targets with
            uniform noise of +-``noise_rad`` (``robot_rise.proof.noise``); each must hold the
            torque bound and end where the noiseless replay does (0: no noise check).
        noise_rad: the target noise [rad] (``robot_rise.constants.TARGET_NOISE_RAD``).
        noise_hold_s: each noisy replay goes on this long after the trajectory's end [s] (the
            landing's last impacts; the noiseless replay judges the rest of the hold).
        noise_seed: seed of the noise (a proof is repeatable).
    """

    envelope_margin: float = ENVELOPE_MARGIN
    proof_headroom: float = PROOF_HEADROOM
    self_penetration_tolerance_m: float = DEFAULT_CONTACT_TOLERANCE_M
    min_zmp_margin_m: float = 0.0
    balance_tolerance_m: float = 0.005
    balance_hold_s: float = 0.1
    divergence_rad: float = 0.33
    divergence_hold_s: float = 0.4
    hold_s: float = 3.0
    ensemble: bool = True
    combined_variants: int = 0
    noise_replays: int = 6
    noise_rad: float = TARGET_NOISE_RAD
    noise_hold_s: float = 0.5
    noise_seed: int = 0

    def proving(self) -> ProofConfig:
        """This standard as the filter proves with it: the headroom taken off the bound
        (``envelope_margin + proof_headroom``, no headroom left to add again)."""
        return dataclasses.replace(self, envelope_margin=self.envelope_margin + self.proof_headroom, proof_headroom=0.0)
