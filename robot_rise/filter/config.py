"""The dynamics filter's tuning: one frozen ``FilterConfig`` (how targets are reshaped; the proof's standard within)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from robot_rise.proof.config import ProofConfig

__all__ = ["FilterConfig"]


@dataclass(frozen=True)
class FilterConfig:
    """Tuning of the dynamics filter.

    Attributes:
        proof: the standard every replay of the filter is judged by (``robot_rise.proof.ProofConfig``).
        soft_iterations: extra iterations spent on balance/divergence violations once the motion
            is proven (stands, within the envelope); the best proven motion is kept.
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
        ensemble_rounds: times a motion some variant falls with is slowed and proven again.
        noise_rounds: times (in total, per filter call) a motion a noisy replay breaks is slowed
            there and proven again.
        trim_levels: once the nominal filter proves a slowed motion, the time its coarse steps
            added (``slow_factor`` on padded windows) is cut back by bisection over this many
            nominal replays (``loop._trim``); the shortest proven there then takes the noise check
            and the ensemble proof at the same margins, and where either fails the untrimmed one
            takes them as before (0: no trimming; ``rise``'s composed proof does not trim).
    """

    proof: ProofConfig = field(default_factory=ProofConfig)
    soft_iterations: int = 2
    slow_factor: float = 1.6
    window_pad_s: float = 0.15
    blend_s: float = 0.3
    quick_blend_s: float | None = 0.1
    join_overlap_s: float | None = 0.2
    max_iterations: int = 6
    max_duration_s: float = 30.0
    max_stretch: float | None = None
    motion_max_stretch: float | None = None
    ensemble_rounds: int = 3
    noise_rounds: int = 2
    trim_levels: int = 3

    def proving(self) -> FilterConfig:
        """This configuration as the filter proves with it (``ProofConfig.proving``)."""
        return dataclasses.replace(self, proof=self.proof.proving())
