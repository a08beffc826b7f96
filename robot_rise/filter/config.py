"""The dynamics filter's tuning: one frozen ``FilterConfig`` (margins, tolerances, iteration budget)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from robot_rise.constants import ENVELOPE_MARGIN, PROOF_HEADROOM, TARGET_NOISE_RAD
from robot_rise.validity import DEFAULT_CONTACT_TOLERANCE_M

__all__ = ["FilterConfig"]


@dataclass(frozen=True)
class FilterConfig:
    """Tuning of the dynamics filter.

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
        soft_iterations: extra iterations spent on balance/divergence violations once the motion
            is proven (stands, within the envelope); the best proven motion is kept.
        divergence_rad: tracking error counted as divergence [rad] (default 1.5 x the servo's
            saturation error: beyond saturation the servo pushes with all it has).
        divergence_hold_s: how long the error must last to count [s].
        slow_factor: time stretch applied to an offending window per iteration.
        window_pad_s: padding around an offending window [s].
        blend_s: the shortest step from one part's last targets to the next part's first
            (``join_with_blend``: plan to library frame, a composed approach to the motion's
            first targets, a failed attempt to the rise after it) [s]; a larger mismatch takes
            longer, at 2 rad/s. Where the plan ends on the frame the step is a pause; 0.1 s
            makes every flat-ground rise 0.2 s sooner (issue 17, BENCHMARKS.md) but a prone start
            on the 10 deg slope then falls (sim_tests/test_environments.py): the pause lets the
            body settle before the motion, so it stays 0.3 s where ``quick_blend_s`` does not prove.
        quick_blend_s: ``rise`` joins each candidate's plan to its motion with this shorter
            step where the overlap below is not proven or not the quicker, and where neither is
            proven with ``blend_s`` (None: ``blend_s`` only).
        join_overlap_s: ``rise`` first starts each candidate's motion this long before its
            approach ends, the two cross-faded (``join_with_overlap``; at most half the approach):
            no stop and no pause at the join. Where that is proven but slowed past what the
            ``quick_blend_s`` step could at best give, the step is tried too and the quicker
            proven one kept (OP3, 120 postures around the median of the 300-posture protocol:
            the overlap stood sooner than the step on 79, later on 35; the better of the two
            took the protocol's median from 4.18 to 3.99 s; BENCHMARKS.md issue 17). None: no
            overlap.
        max_iterations: filter iterations before giving up.
        hold_s: time the final targets are held while the judge watches [s].
        max_duration_s: never stretch the motion beyond this [s].
        max_stretch: the nominal filter stops slowing the library motion (from the filter's
            ``join_row``; the whole trajectory without one) at this multiple of its commanded
            duration (None: only ``max_duration_s``). ``rise`` sets it: a library motion that needs
            more slowing is not the quick one its candidate promised (a momentum motion slowed
            falls anyway), and the next candidate is cheaper to try than ever longer replays. The
            approach before the join may be slowed as far as ``max_duration_s`` (a side posture
            kept on its side), and so may the ensemble's rounds (on a slope the variants need
            the slower stance).
        motion_max_stretch: the library motion's own timing window
            (``robot_rise.library.Motion.max_stretch``): neither the nominal filter nor the
            ensemble's rounds slow the part from ``join_row`` on beyond this multiple of its
            commanded duration (None: no window of its own). ``rise`` sets it per candidate.
        ensemble: prove on every model variant too (``robot_rise.sim.variants.ENSEMBLE``).
        combined_variants: with ``ensemble``, also prove on the first this many combined random
            variants (``robot_rise.sim.variants.combined_variants``); ``rise`` sets it per
            candidate from ``robot_rise.library.Motion.combined_variants``.
        ensemble_rounds: times a motion some variant falls with is slowed and proven again.
        noise_replays: the nominal model also replays this many copies of the proven targets with
            uniform noise of +-``noise_rad`` (``robot_rise.filter.noise``); each must hold the
            torque bound and end where the noiseless replay does (0: no noise check).
        noise_rad: the target noise [rad] (``robot_rise.constants.TARGET_NOISE_RAD``).
        noise_hold_s: each noisy replay goes on this long after the trajectory's end [s] (the
            landing's last impacts; the noiseless replay judges the rest of the hold).
        noise_seed: seed of the noise (a proof is repeatable).
        noise_rounds: times (in total, per filter call) a motion a noisy replay breaks is slowed
            there and proven again.
        trim_levels: once the nominal filter proves a slowed motion, the time its coarse steps
            added (``slow_factor`` on padded windows) is cut back by bisection over this many
            nominal replays (``loop._trim``); the shortest proven there then takes the noise check
            and the ensemble proof at the same margins, and where either fails the untrimmed one
            takes them as before (0: no trimming; ``rise``'s composed proof does not trim).
    """

    envelope_margin: float = ENVELOPE_MARGIN
    proof_headroom: float = PROOF_HEADROOM
    self_penetration_tolerance_m: float = DEFAULT_CONTACT_TOLERANCE_M
    min_zmp_margin_m: float = 0.0
    balance_tolerance_m: float = 0.005
    balance_hold_s: float = 0.1
    soft_iterations: int = 2
    divergence_rad: float = 0.33
    divergence_hold_s: float = 0.4
    slow_factor: float = 1.6
    window_pad_s: float = 0.15
    blend_s: float = 0.3
    quick_blend_s: float | None = 0.1
    join_overlap_s: float | None = 0.2
    max_iterations: int = 6
    hold_s: float = 3.0
    max_duration_s: float = 30.0
    max_stretch: float | None = None
    motion_max_stretch: float | None = None
    ensemble: bool = True
    combined_variants: int = 0
    ensemble_rounds: int = 3
    noise_replays: int = 6
    noise_rad: float = TARGET_NOISE_RAD
    noise_hold_s: float = 0.5
    noise_seed: int = 0
    noise_rounds: int = 2
    trim_levels: int = 3

    def proving(self) -> FilterConfig:
        """This configuration as the filter proves with it: the headroom taken off the bound
        (``envelope_margin + proof_headroom``, no headroom left to add again)."""
        return dataclasses.replace(self, envelope_margin=self.envelope_margin + self.proof_headroom, proof_headroom=0.0)
